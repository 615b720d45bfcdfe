"""Result cache for the executors: a finished job is kept under a key that changes with anything that
could change its result, so a rerun reuses finished work and a changed input or code never returns a
stale result.

The key of ``fn(job)`` (:func:`job_key`) is the SHA-256 of the canonical JSON of

* every input: the job dict itself (numbers, strings, lists, tables; numpy arrays by dtype, shape
  and bytes; attrs records by their fields; anything else by its pickle);
* the knitframe version, and those of numpy and scipy;
* the job function's code (:func:`code_hash`): its compiled code (bytecode, constants, names and
  defaults, recursively through nested functions; what runs, even if the file changed after
  import), and the source of the module that defines it together with every module of knitframe
  and of its plugins that module imports, directly or through others, anywhere in the file
  (function-level imports too);
* the source of the modules the job names at run time — plugins chosen by name from a config,
  which no import statement reveals: a job function lists them with a ``cache_modules(job)``
  attribute (the sweep's point function, :func:`knitframe.sweep.run_point`, names its solver,
  contact law, linear solver, pattern, yarn model, reduced model and fitter plugins; the ladder's
  :func:`knitframe.ladder.run_rung` its own), and their imports are followed the same way.

Solver options are part of the job, so a changed option changes the key too. Sources are read from
disk: worker processes import them from there. A module edited in an interactive session but not
reloaded keeps running its old code in that process; restart it (or reload) before relying on the
cache.

Results are pickled to ``<directory>/<key>.pkl`` and written atomically (rename after write). A
file that cannot be read back (a truncated copy, classes that changed) counts as missing. The
default directory is :func:`default_cache_dir`; ``knitframe cache clear`` empties it.

Failures are not results: :class:`JobFailure` is what an executor returns in place of a job that
raised, when asked to keep going (``failures = "keep"``); it is never cached.
"""

from __future__ import annotations

import ast
import hashlib
import importlib.util
import json
import math
import os
import pickle
import re
import sys
import types
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import attrs

from knitframe.outdir import write_atomic

__all__ = [
    "job_key",
    "job_keys",
    "code_hash",
    "module_sources",
    "JobCache",
    "JobFailure",
    "failure_reason",
    "default_cache_dir",
    "KEY_RECIPE",
]

#: version of the key's recipe; bumped whenever what goes into a key changes
KEY_RECIPE = 2
_KEY_FILE = re.compile(r"^[0-9a-f]{64}\.pkl$")
_TMP_FILE = re.compile(r"^\.job-.*\.tmp$")


# ------------------------------------------------------------------------------------------ failures
@attrs.frozen
class JobFailure:
    """A job that raised: its one-line reason (``ExceptionName: message``). Never cached."""

    reason: str

    def __str__(self) -> str:
        return self.reason


def failure_reason(exc: BaseException) -> str:
    """One line naming an exception and its message (whitespace and line breaks collapsed)."""
    text = " ".join(str(exc).split())
    name = type(exc).__name__
    return f"{name}: {text}" if text else name


# ------------------------------------------------------------------------------------------ code
def _code_digest(code: types.CodeType, h: Any) -> None:
    """Feed a code object into ``h``: bytecode, names and constants, recursively; no file names or
    line numbers (moving a function does not change it), and sets in a fixed order (their iteration
    order depends on the process's hash seed)."""
    h.update(code.co_code)
    h.update(
        repr(
            (
                code.co_name,
                code.co_names,
                code.co_varnames,
                code.co_freevars,
                code.co_cellvars,
                code.co_argcount,
                code.co_kwonlyargcount,
                code.co_flags,
            )
        ).encode()
    )
    for c in code.co_consts:
        _const_digest(c, h)


def _const_digest(c: Any, h: Any) -> None:
    if isinstance(c, types.CodeType):
        h.update(b"<code>")
        _code_digest(c, h)
    elif isinstance(c, (frozenset, set)):
        h.update(b"<set>" + repr(sorted(repr(x) for x in c)).encode())
    elif isinstance(c, tuple):
        h.update(b"<tuple>")
        for x in c:
            _const_digest(x, h)
        h.update(b"</tuple>")
    else:
        h.update(f"{type(c).__name__}:{c!r}".encode())


def _function_digest(fn: Callable[..., Any]) -> str:
    """Hash of what a callable runs: its code, defaults and closure (functools.partial: its function
    and arguments; a callable object: its class's ``__call__``)."""
    import functools

    h = hashlib.sha256()
    if isinstance(fn, functools.partial):
        h.update(_function_digest(fn.func).encode())
        h.update(_canonical_json({"args": list(fn.args), "keywords": fn.keywords}).encode())
        return h.hexdigest()
    target = fn
    # a class always has __call__ (its metaclass's): the test is that fn is an instance, not a class
    if not hasattr(target, "__code__") and hasattr(type(fn), "__call__") and not isinstance(fn, type):  # noqa: B004
        target = type(fn).__call__
        h.update(_canonical_json(fn).encode())  # the object's own state
    target = getattr(target, "__func__", target)  # bound methods
    code = getattr(target, "__code__", None)
    if code is None:  # a builtin: its name is all there is
        h.update(repr(getattr(fn, "__qualname__", fn)).encode())
        return h.hexdigest()
    _code_digest(code, h)
    h.update(
        _canonical_json(
            {"defaults": list(target.__defaults__ or ()), "kwdefaults": dict(target.__kwdefaults__ or {})}
        ).encode()
    )
    for cell in target.__closure__ or ():
        try:
            value = cell.cell_contents
        except ValueError:  # an empty cell
            continue
        if callable(value) and hasattr(value, "__code__"):
            h.update(_function_digest(value).encode())
        else:
            h.update(_canonical_json(value).encode())
    return h.hexdigest()


def _is_ours(name: str, roots: set[str]) -> bool:
    top = name.split(".")[0]
    return top == "knitframe" or top.startswith("knitframe_") or top in roots


def _module_file(name: str) -> Path | None:
    """The file a module is (or would be) loaded from; None for builtins, namespaces and unknown names."""
    mod = sys.modules.get(name)
    origin = getattr(mod, "__file__", None) if mod is not None else None
    if origin is None:
        try:
            spec = importlib.util.find_spec(name)
        except (ImportError, ValueError, AttributeError):
            return None
        origin = spec.origin if spec is not None and spec.has_location else None
    return Path(origin) if origin else None


#: module imports found in a source text, by the text's SHA-256 (parsing is the slow part)
_IMPORTS: dict[tuple[str, str, bool], tuple[str, ...]] = {}


def _imports(digest: str, text: bytes, name: str, package: bool) -> tuple[str, ...]:
    """Modules a source file imports anywhere (module level and inside functions), resolved to
    absolute names; ``from pkg import sub`` gives both ``pkg`` and ``pkg.sub``."""
    memo = (digest, name, package)
    if memo in _IMPORTS:
        return _IMPORTS[memo]
    try:
        tree = ast.parse(text)
    except (SyntaxError, ValueError):
        _IMPORTS[memo] = ()
        return ()
    parent = name if package else name.rpartition(".")[0]
    found: list[str] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                try:
                    base = importlib.util.resolve_name("." * node.level + base, parent) if parent else base
                except (ImportError, ValueError):
                    continue
            if base:
                found.append(base)
                found += [f"{base}.{a.name}" for a in node.names if a.name != "*"]
    _IMPORTS[memo] = tuple(dict.fromkeys(found))
    return _IMPORTS[memo]


def module_sources(modules: Iterable[str]) -> dict[str, str]:
    """SHA-256 of the source of each module named and of every module of knitframe, its plugins and
    the named modules' own packages that they import, transitively: ``{module: digest}``.

    Names that are not modules (``from knitframe import hookimpl`` also offers ``knitframe.hookimpl``)
    and modules without a file are left out.
    """
    seeds = [m for m in modules if m]
    roots = {m.split(".")[0] for m in seeds}
    todo = list(seeds)
    out: dict[str, str] = {}
    seen: set[str] = set()
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        path = _module_file(name)
        if path is None or not path.is_file():
            continue
        data = path.read_bytes()
        digest = hashlib.sha256(data).hexdigest()
        out[name] = digest
        if path.suffix == ".py":
            for imp in _imports(digest, data, name, path.name == "__init__.py"):
                if imp not in seen and _is_ours(imp, roots):
                    todo.append(imp)
    return dict(sorted(out.items()))


def code_hash(fn: Callable[..., Any], modules: Iterable[str] = ()) -> str:
    """Hash of a job function's code and of the source it depends on (see the module docstring)."""
    home = getattr(fn, "__module__", None) or getattr(getattr(fn, "func", None), "__module__", None) or ""
    payload = {"function": _function_digest(fn), "sources": module_sources([home, *modules])}
    return hashlib.sha256(_canonical_json(payload).encode()).hexdigest()


# ------------------------------------------------------------------------------------------ keys
def _plain(obj: Any) -> Any:
    """Canonical plain data of a job value; never a lossy ``str()`` (two different values must never
    meet in one key)."""
    import numpy as np

    if obj is None or isinstance(obj, (bool, int, str)):
        return obj
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else {"float": repr(obj)}
    if isinstance(obj, Mapping):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return {"set": sorted((_plain(v) for v in obj), key=lambda v: json.dumps(v, sort_keys=True))}
    if isinstance(obj, np.ndarray):
        arr = np.ascontiguousarray(obj)
        return {"ndarray": [arr.dtype.str, list(arr.shape), hashlib.sha256(arr.tobytes()).hexdigest()]}
    if isinstance(obj, (np.floating, np.integer, np.bool_)):
        return _plain(obj.item())
    if isinstance(obj, Path):
        return {"path": str(obj)}
    if attrs.has(type(obj)):
        fields = {f.name: _plain(getattr(obj, f.name)) for f in attrs.fields(type(obj))}
        return {"record": f"{type(obj).__module__}.{type(obj).__qualname__}", "fields": fields}
    try:  # anything else by its pickle: deterministic for one value, different for different ones
        return {"pickle": hashlib.sha256(pickle.dumps(obj, protocol=4)).hexdigest()}
    except Exception:  # noqa: BLE001 - unpicklable: a key that never matches again (no reuse, never stale)
        return {"unhashable": f"{type(obj).__qualname__}@{id(obj)}"}


def _canonical_json(obj: Any) -> str:
    return json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"), allow_nan=False)


def _environment() -> dict[str, str]:
    import numpy
    import scipy

    from knitframe.version import __version__

    return {"knitframe": __version__, "numpy": numpy.__version__, "scipy": scipy.__version__}


def _fn_name(fn: Callable[..., Any]) -> str:
    target = getattr(fn, "func", fn)
    return f"{getattr(target, '__module__', '')}.{getattr(target, '__qualname__', type(target).__qualname__)}"


def _cache_modules(fn: Callable[..., Any], job: Mapping[str, Any]) -> tuple[str, ...]:
    extra = getattr(fn, "cache_modules", None) or getattr(getattr(fn, "func", None), "cache_modules", None)
    return tuple(sorted(set(extra(job)))) if extra is not None else ()


def job_keys(fn: Callable[..., Any], jobs: Iterable[Mapping[str, Any]]) -> list[str]:
    """:func:`job_key` of every job; the code is hashed once per distinct set of modules."""
    env, name, codes, keys = _environment(), _fn_name(fn), {}, []
    for job in jobs:
        mods = _cache_modules(fn, job)
        if mods not in codes:
            codes[mods] = code_hash(fn, mods)
        text = _canonical_json(
            {"recipe": KEY_RECIPE, "fn": name, "code": codes[mods], "env": env, "job": job}
        )
        keys.append(hashlib.sha256(text.encode()).hexdigest())
    return keys


def job_key(fn: Callable[..., Any], job: Mapping[str, Any]) -> str:
    """SHA-256 of every input of ``fn(job)``, the versions, and the code that computes it."""
    return job_keys(fn, [job])[0]


# ------------------------------------------------------------------------------------------ store
def default_cache_dir() -> Path:
    """``$KNITFRAME_CACHE_DIR``, else ``$XDG_CACHE_HOME/knitframe/jobs``, else ``~/.cache/knitframe/jobs``."""
    env = os.environ.get("KNITFRAME_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base).expanduser() / "knitframe" / "jobs"


class JobCache:
    """Pickled results under ``directory/<key>.pkl``, written atomically (rename after write).

    ``directory=None`` disables the cache: nothing is read or written. The folder is created unless
    ``create`` is false (to look at or clear an existing cache).
    """

    def __init__(self, directory: str | Path | None, *, create: bool = True):
        self.directory = Path(directory) if directory else None
        if self.directory is not None and create:
            self.directory.mkdir(parents=True, exist_ok=True)

    def path(self, key: str) -> Path | None:
        return None if self.directory is None else self.directory / f"{key}.pkl"

    def has(self, key: str) -> bool:
        p = self.path(key)
        return p is not None and p.is_file()

    def get(self, key: str) -> tuple[bool, Any]:
        """``(True, result)`` when cached and readable, else ``(False, None)``."""
        p = self.path(key)
        if p is None or not p.is_file():
            return False, None
        try:
            with open(p, "rb") as fh:
                return True, pickle.load(fh)
        except Exception:  # noqa: BLE001 - unreadable (truncated, classes changed): recompute and replace
            return False, None

    def split(
        self, fn: Callable[..., Any], jobs: list[Mapping[str, Any]]
    ) -> tuple[list[str], list[Any], list[int]]:
        """``(keys, results, todo)``: each job's key, cached results in place (None elsewhere), and
        the indices of the jobs still to run."""
        keys = job_keys(fn, jobs)
        results: list[Any] = [None] * len(jobs)
        todo = []
        for i, k in enumerate(keys):
            hit, value = self.get(k)
            if hit:
                results[i] = value
            else:
                todo.append(i)
        return keys, results, todo

    def put(self, key: str, value: Any) -> None:
        """Keep a result (a :class:`JobFailure` is never kept)."""
        if self.directory is None or isinstance(value, JobFailure):
            return
        write_atomic(self.directory / f"{key}.pkl", lambda fh: pickle.dump(value, fh), prefix=".job-")

    def entries(self) -> list[Path]:
        """The cache's own files: results (``<64 hex>.pkl``) and leftovers of interrupted writes."""
        if self.directory is None or not self.directory.is_dir():
            return []
        return sorted(
            p
            for p in self.directory.iterdir()
            if p.is_file() and (_KEY_FILE.match(p.name) or _TMP_FILE.match(p.name))
        )

    def info(self) -> tuple[int, int]:
        """``(results, bytes)`` held."""
        files = self.entries()
        return sum(1 for p in files if p.suffix == ".pkl"), sum(p.stat().st_size for p in files)

    def clear(self) -> tuple[int, int]:
        """Delete the cache's own files (nothing else in the folder); returns ``(files, bytes)`` removed."""
        n = size = 0
        for p in self.entries():
            try:
                s = p.stat().st_size
                p.unlink()
            except FileNotFoundError:  # another process removed it meanwhile
                continue
            n, size = n + 1, size + s
        return n, size
