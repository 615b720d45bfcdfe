"""The folder a command writes into, guarded so that a run never destroys or loses anything.

Every command that writes files (``run``, ``fit``, ``geometry``) goes through :class:`OutputDir`:

- ``.``, ``..``, the current folder or any of its parents, a file, and a place that cannot be
  written are refused before any work, with one line naming the option;
- an existing folder that holds anything is refused unless the user gives ``--resume`` (the same
  config's unfinished or finished run) or ``--overwrite`` (which replaces only the files an earlier
  knitframe run listed in its ``summary.json``, never anything else);
- one lock per folder (:mod:`filelock`): a second process stops at once and names the folder;
- work happens in ``DIR/.knitframe/`` (``staging/`` for outputs, ``checkpoints/`` for resumable
  state); the outputs move into ``DIR`` only when the whole run succeeded, then ``summary.json``
  is written last, listing exactly the files that are there;
- a failed run removes what it created, except checkpoints worth resuming from.

Layout while a run is going on (or after it was killed)::

    DIR/.knitframe/lock          the lock file
    DIR/.knitframe/run.json      which command and config (fingerprint) the run belongs to
    DIR/.knitframe/staging/      outputs so far
    DIR/.knitframe/checkpoints/  converged states for --resume
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from knitframe.errors import ConfigError

__all__ = ["OutputDir", "WORK", "fingerprint", "add_overwrite_argument"]

#: the hidden folder that holds a run's work until it succeeds
WORK = ".knitframe"


def fingerprint(obj: Any) -> str:
    """SHA-256 of an object's canonical JSON: which config (or command line) a run belongs to."""
    import hashlib

    return hashlib.sha256(json.dumps(obj, sort_keys=True, default=str).encode()).hexdigest()


def add_overwrite_argument(parser: Any) -> None:
    """The ``--overwrite`` option of every command that writes an output folder."""
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace an earlier knitframe run's outputs in --out (other files are never touched)",
    )


def _previous_outputs(out: Path) -> tuple[set[str], str | None]:
    """Files an earlier knitframe run wrote into ``out`` (from its summary.json), and its fingerprint."""
    summary = out / "summary.json"
    try:
        data = json.loads(summary.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return set(), None
    if not isinstance(data, dict) or "knitframe" not in data or not isinstance(data.get("outputs"), list):
        return set(), None
    return {str(p) for p in data["outputs"]} | {"summary.json"}, data.get("fingerprint")


class OutputDir:
    """Context manager that owns one output folder for the length of a run.

    Parameters
    ----------
    out : path
        The folder the user named.
    option : str
        How the user named it (``--out``), for error messages.
    command : str
        The command writing it (``run``, ``fit``, ``geometry``).
    fingerprint : str
        Identifies the inputs; ``--resume`` is only allowed for the same fingerprint.
    resume, overwrite : bool
        The user's ``--resume`` and ``--overwrite``.

    Use::

        with OutputDir(out, command="fit", fingerprint=fp) as od:
            write(od.staging / "params.json")
            od.commit({"command": "fit"})       # moves the outputs into place, writes summary.json
    """

    def __init__(
        self,
        out: str | Path,
        *,
        option: str = "--out",
        command: str,
        fingerprint: str = "",
        resume: bool = False,
        overwrite: bool = False,
    ):
        self.option = option
        self.command = command
        self.fingerprint = fingerprint
        self.resume = resume
        self.overwrite = overwrite
        text = str(out)
        if not text.strip():
            raise ConfigError(option, "is empty; name a folder")
        self.given = text
        self.out = Path(os.path.abspath(Path(text).expanduser()))
        self.work = self.out / WORK
        self.staging = self.work / "staging"
        self.checkpoints = self.work / "checkpoints"
        self._created: list[Path] = []  # folders this run made, outermost first
        self._lock: Any = None
        self.resumed = False  #: True when an unfinished run's work was found and kept
        self.committed: list[str] = []

    # ------------------------------------------------------------------ checks before any work
    def _fail(self, problem: str) -> ConfigError:
        return ConfigError(self.option, f"{self.given}: {problem}")

    def check(self) -> None:
        """Every refusal that needs no lock: the place itself and what is already there."""
        real = Path(os.path.realpath(self.out))
        cwd = Path(os.path.realpath(Path.cwd()))
        if real == cwd or real in cwd.parents:
            raise self._fail("is the current folder or one of its parents; name a new folder for the outputs")
        if self.out.exists() and not self.out.is_dir():
            raise self._fail("is a file, not a folder")
        if self.out.is_symlink() and not self.out.exists():
            raise self._fail("is a broken link")
        base = self.out
        while not base.exists():
            if base.is_symlink():
                raise self._fail(f"{base} is a broken link")
            base = base.parent
        if not base.is_dir():
            raise self._fail(f"cannot create it: {base} is a file")
        if not os.access(base, os.W_OK | os.X_OK):
            raise self._fail(f"cannot write in {base}")
        if self.out.is_dir():
            if self._busy():
                raise self._fail(
                    "another knitframe run is writing to this folder; wait for it or name another folder"
                )
            self._check_contents()

    def _busy(self) -> bool:
        """Whether another process holds the folder's lock (probed without creating anything)."""
        from filelock import FileLock, Timeout

        path = self.work / "lock"
        if not path.is_file():
            return False
        probe = FileLock(str(path), timeout=0)
        try:
            probe.acquire()
        except Timeout:
            return True
        except OSError:
            return False
        probe.release()
        return False

    def _check_contents(self) -> None:
        try:
            names = {p.name for p in self.out.iterdir()}
        except OSError as e:
            raise self._fail(f"cannot read it: {e.strerror}") from None
        unfinished = (self.work / "run.json").exists()
        if unfinished:
            info = self._run_info()
            if self.resume and info.get("fingerprint") != self.fingerprint:
                raise self._fail(
                    f"holds an unfinished '{info.get('command', '?')}' run of another config; "
                    "--resume needs the same config (or give --overwrite)"
                )
            if not (self.resume or self.overwrite):
                raise self._fail(
                    "holds an unfinished run; give --resume to continue it or --overwrite to start again"
                )
        others = names - {WORK}
        if not others:
            return
        previous, fp = _previous_outputs(self.out)
        if self.overwrite:
            return
        if self.resume:
            if unfinished or (previous and fp == self.fingerprint):
                return
            if previous:
                raise self._fail("holds a finished run of another config; --resume needs the same config")
            raise self._fail("holds no knitframe run to resume")
        raise self._fail(
            "is not empty; name a new folder, or give --overwrite to replace the outputs of an "
            "earlier knitframe run there (other files are never touched)"
        )

    def _run_info(self) -> dict[str, Any]:
        try:
            data = json.loads((self.work / "run.json").read_text(encoding="utf-8"))
            return data if isinstance(data, dict) else {}
        except (OSError, ValueError):
            return {}

    # ------------------------------------------------------------------ enter / exit
    def __enter__(self) -> OutputDir:
        self.check()
        try:
            self._mkdirs(self.out)
            self._mkdirs(self.work)
        except OSError as e:
            self._remove_created()
            raise self._fail(f"cannot create it: {e.strerror}") from None
        self._acquire()
        try:
            self._check_contents()  # again, now that no other run can change the folder
            unfinished = (self.work / "run.json").exists()
            if unfinished and self.resume:
                self.resumed = True
            elif unfinished:  # --overwrite of an unfinished run: its work goes
                shutil.rmtree(self.staging, ignore_errors=True)
                shutil.rmtree(self.checkpoints, ignore_errors=True)
            self.staging.mkdir(exist_ok=True)
            self.checkpoints.mkdir(exist_ok=True)
            _write_atomic(
                self.work / "run.json",
                json.dumps(
                    {
                        "command": self.command,
                        "fingerprint": self.fingerprint,
                        "pid": os.getpid(),
                        "started": time.strftime("%Y-%m-%dT%H:%M:%S"),
                    },
                    indent=2,
                )
                + "\n",
            )
        except BaseException:
            self._abandon(keep_checkpoints=False)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._lock is None:  # committed
            return
        self._abandon(keep_checkpoints=True)

    def _mkdirs(self, path: Path) -> None:
        missing = []
        p = path
        while not p.exists():
            missing.append(p)
            p = p.parent
        for p in reversed(missing):
            try:
                p.mkdir()
            except FileExistsError:
                continue  # another process made it first: not ours
            self._created.append(p)

    def _acquire(self) -> None:
        from filelock import FileLock, Timeout

        lock = FileLock(str(self.work / "lock"), timeout=0)
        try:
            lock.acquire()
        except Timeout:
            self._remove_created()
            raise self._fail(
                "another knitframe run is writing to this folder; wait for it or name another folder"
            ) from None
        except OSError as e:
            self._remove_created()
            raise self._fail(f"cannot lock it: {e.strerror}") from None
        self._lock = lock

    def _release(self) -> None:
        if self._lock is not None:
            self._lock.release()
            self._lock = None

    def _abandon(self, *, keep_checkpoints: bool) -> None:
        """After a failure: keep resumable checkpoints, remove everything else this run made."""
        has_checkpoints = (
            keep_checkpoints
            and self.checkpoints.is_dir()
            and any(p.is_file() for p in self.checkpoints.rglob("*"))
        )
        if not has_checkpoints:
            shutil.rmtree(self.work, ignore_errors=True)
        self._release()
        if not has_checkpoints:
            self._remove_created()

    def _remove_created(self) -> None:
        for p in reversed(self._created):
            try:
                p.rmdir()  # only if empty: anything another program put there stays
            except FileNotFoundError:
                continue
            except OSError:
                break
        self._created.clear()

    # ------------------------------------------------------------------ success
    def commit(self, summary: dict[str, Any]) -> dict[str, Any]:
        """Move the staged outputs into the folder and write ``summary.json`` listing them.

        Nothing moves if any output would replace a file that no earlier knitframe run wrote.
        Returns the summary as written (``outputs`` is the sorted list of files moved).
        """
        staged = sorted(str(p.relative_to(self.staging)) for p in self.staging.rglob("*") if p.is_file())
        staged = [s for s in staged if s != "summary.json"]
        previous, _ = _previous_outputs(self.out)
        clash = [s for s in staged + ["summary.json"] if (self.out / s).exists() and s not in previous]
        if clash:
            raise self._fail(
                f"would replace '{clash[0]}', which no knitframe run wrote; move it or name another folder"
            )
        for old in sorted(previous - set(staged) - {"summary.json"}):
            # an earlier run's own output that this run does not make again
            p = self.out / old
            if p.is_file():
                p.unlink()
                _prune_empty(p.parent, self.out)
        summary = {**summary, "outputs": staged, "fingerprint": self.fingerprint}
        for rel in staged:
            target = self.out / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(self.staging / rel, target)
        missing = [s for s in staged if not (self.out / s).is_file()]
        if missing:  # pragma: no cover - a file system that lost a rename
            raise OSError(f"outputs missing after the move: {missing}")
        _write_atomic(self.out / "summary.json", json.dumps(summary, indent=2) + "\n")
        shutil.rmtree(self.work, ignore_errors=True)
        self._release()
        self.committed = staged
        return summary


def _prune_empty(folder: Path, stop: Path) -> None:
    while folder != stop and folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
        folder = folder.parent


def _write_atomic(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
