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
- a failed run removes what it created, except checkpoints worth resuming from;
- the file system refusing a write (a full disk, a quota, a read-only or removed folder) is a
  :class:`~knitframe.errors.WriteError` naming the file as the user will see it, with the partial
  file removed; it says ``--resume`` when the run's checkpoints are kept.

Layout while a run is going on (or after it was killed)::

    DIR/.knitframe/lock          the lock file
    DIR/.knitframe/run.json      which command and config (fingerprint) the run belongs to
    DIR/.knitframe/staging/      outputs so far
    DIR/.knitframe/checkpoints/  converged states for --resume
"""

from __future__ import annotations

import errno
import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

from knitframe.errors import ConfigError, WriteError, name_written, written_file

__all__ = ["OutputDir", "WORK", "fingerprint", "add_overwrite_argument", "write_atomic"]

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
            if e.errno in (errno.ENOSPC, errno.EDQUOT):
                raise self._write_error(e, checkpoints=False) from None
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
            write_atomic(
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
        except BaseException as e:
            self._failed(e)
            raise
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if self._lock is not None:  # not committed
            self._failed(exc)

    def _failed(self, exc: BaseException | None) -> None:
        """After a failure: remove what the run made but its checkpoints (an unfinished run's stay for
        ``--resume``); the file system refusing a write is raised again as a :class:`WriteError`."""
        if not isinstance(exc, OSError) or isinstance(exc, WriteError):
            self._abandon()
            return
        partial = written_file(exc.__traceback__)
        if partial is not None and Path(os.path.abspath(partial)).is_relative_to(self.work):
            Path(partial).unlink(missing_ok=True)  # half written, and the run's own
        kept = self._abandon()
        raise self._write_error(exc, checkpoints=kept) from exc

    def _write_error(self, error: OSError, *, checkpoints: bool) -> WriteError:
        """``error`` as one line naming the file as the user will see it (no file: the folder)."""
        found = WriteError.of(error)
        if found.path is None:
            return WriteError(error, self.given, checkpoints=checkpoints)
        path = Path(os.path.abspath(found.path))
        if path == self.work / "summary.json":
            path = self.out / "summary.json"
        elif path.is_relative_to(self.staging):  # a staged output: where it was going
            path = self.out / path.relative_to(self.staging)
        if not path.is_relative_to(self.out):
            return WriteError(error, found.path, writing=found.writing, checkpoints=checkpoints)
        rel = path.relative_to(self.out)
        shown = self.given if rel == Path(".") else os.path.join(self.given, rel)
        return WriteError(error, shown, checkpoints=checkpoints)

    def _mkdirs(self, path: Path) -> list[Path]:
        """Make ``path`` and its missing parents; the folders made, outermost first."""
        missing = []
        p = path
        while not p.exists():
            missing.append(p)
            p = p.parent
        made = []
        for p in reversed(missing):
            try:
                p.mkdir()
            except FileExistsError:
                continue  # another process made it first: not ours
            made.append(p)
        self._created += made
        return made

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

    def _abandon(self) -> bool:
        """After a failure: keep resumable checkpoints, remove everything else this run made.

        Returns whether checkpoints were kept."""
        has_checkpoints = self.checkpoints.is_dir() and any(p.is_file() for p in self.checkpoints.rglob("*"))
        if not has_checkpoints:
            shutil.rmtree(self.work, ignore_errors=True)
        self._release()
        if not has_checkpoints:
            self._remove_created()
        return has_checkpoints

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

        Nothing moves if any output would replace a file that no earlier knitframe run wrote. If a
        move fails, the folder is put back as it was: the outputs go back to staging and the earlier
        run's files they replaced (set aside until the end) return. ``summary.json`` is written
        before anything moves (the only write that needs space) and renamed into place last.
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
        summary = {**summary, "outputs": staged, "fingerprint": self.fingerprint}
        write_atomic(self.work / "summary.json", json.dumps(summary, indent=2) + "\n")
        aside = self.work / "replaced"
        undo: list[tuple[Path, Path] | Path] = []  # (back to, from) of every move, and folders made
        try:
            for rel in staged:
                target = self.out / rel
                undo += self._mkdirs(target.parent)
                if target.exists():  # an earlier run's output
                    undo += self._mkdirs((aside / rel).parent)
                    os.replace(target, aside / rel)
                    undo.append((target, aside / rel))
                os.replace(self.staging / rel, target)
                undo.append((self.staging / rel, target))
            missing = [s for s in staged if not (self.out / s).is_file()]
            if missing:  # pragma: no cover - a file system that lost a rename
                raise OSError(f"outputs missing after the move: {missing}")
            os.replace(self.work / "summary.json", self.out / "summary.json")
        except OSError:
            for step in reversed(undo):
                try:
                    if isinstance(step, tuple):
                        os.replace(step[1], step[0])
                    else:
                        step.rmdir()
                except OSError:
                    continue
            (self.work / "summary.json").unlink(missing_ok=True)
            raise
        for old in sorted(previous - set(staged) - {"summary.json"}):
            # an earlier run's own output that this run does not make again
            p = self.out / old
            if p.is_file():
                p.unlink()
                _prune_empty(p.parent, self.out)
        shutil.rmtree(self.work, ignore_errors=True)
        self._release()
        self.committed = staged
        return summary


def _prune_empty(folder: Path, stop: Path) -> None:
    while folder != stop and folder.is_dir() and not any(folder.iterdir()):
        folder.rmdir()
        folder = folder.parent


def write_atomic(
    path: Path, data: str | Callable[[IO[bytes]], object], *, prefix: str | None = None, suffix: str = ".tmp"
) -> Path:
    """Write a file whole or not at all: a temporary file in its folder (``prefix…suffix``), renamed.

    ``data`` is text (written as UTF-8) or a function that writes into the open binary file. On any
    failure the temporary file is removed, and an :class:`OSError` names ``path``.
    """
    path = Path(path)
    tmp = ""
    try:
        fd, tmp = tempfile.mkstemp(
            dir=path.parent, prefix=f".{path.name}." if prefix is None else prefix, suffix=suffix
        )
        with os.fdopen(fd, "wb") as fh:
            if callable(data):
                data(fh)
            else:
                fh.write(data.encode("utf-8"))
        os.replace(tmp, path)
    except BaseException as e:
        if tmp:
            Path(tmp).unlink(missing_ok=True)
        name_written(e, path, tmp)
        raise
    return path
