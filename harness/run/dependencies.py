"""What a solve read that its cell key cannot see: data files and modules imported by a computed name.

A cell's key covers the source closure of its solver's module (`pcverify.fingerprint`: every module reached by an
`import` statement).  A solver may also read a file beside its module (coefficients in `data.json`) or import a
module by a name it computes (`importlib.import_module("pkg." + name)`); editing either must not leave a cached
result in place.  While a cell solves, a Python audit hook records the files opened for reading, and the
modules new in sys.modules afterwards count as imported by it; the result keeps them (`depends`: each file's
hash and stat, each module's fingerprint), and the cache reads an entry back only while they are unchanged (`stale`).

Recorded: regular files opened for reading that still exist when the solve ends and that it did not write,
outside the interpreter's own folders (the standard library and installed distributions, which count by
version) and outside bytecode and numba caches; modules first imported during a solve of the same solver in
this process (a warm worker imports nothing twice, so the union per solver is kept), outside the standard
library and installed distributions, and not already in the solver module's closure.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import sys
from collections.abc import Iterator
from typing import Any

from pcverify.fingerprint import module_fingerprint, source_closure

SKIPPED_SUFFIXES = (".py", ".pyc", ".pyo", ".so", ".nbi", ".nbc", ".pth")
WRITE_FLAGS = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND


class _Recording:
    """The files and modules one solve touched."""

    def __init__(self, solver: str) -> None:
        self.solver = solver
        self.read: set[str] = set()
        self.written: set[str] = set()


_ACTIVE: list[_Recording] = []
_IMPORTED: dict[str, set[str]] = {}  # solver -> modules first imported during one of its solves in this process
_HOOKED: list[bool] = []


def _prefixes() -> tuple[str, ...]:
    roots = {sys.prefix, sys.base_prefix, sys.exec_prefix, sys.base_exec_prefix}
    cache = os.environ.get("NUMBA_CACHE_DIR")
    return tuple(os.path.join(os.path.realpath(r), "") for r in (*roots, *([cache] if cache else [])))


def _hook(event: str, args: tuple[Any, ...]) -> None:
    """The audit hook: cheap when nothing records (one list test)."""
    if not _ACTIVE:
        return
    rec = _ACTIVE[-1]
    if event == "open":
        path, mode, flags = (tuple(args) + (None, None, None))[:3]
        if isinstance(path, int) or path is None:
            return
        try:
            name = os.path.abspath(os.fsdecode(path))
        except (TypeError, ValueError):
            return
        writes = (any(c in mode for c in "wax+") if isinstance(mode, str)
                  else isinstance(flags, int) and bool(flags & WRITE_FLAGS))
        (rec.written if writes else rec.read).add(name)


@contextlib.contextmanager
def recording(solver: str) -> Iterator[_Recording]:
    """Record what the block (one solve of `solver`) reads; nested blocks record into the innermost."""
    if not _HOOKED:
        sys.addaudithook(_hook)
        _HOOKED.append(True)
    rec = _Recording(solver)
    _ACTIVE.append(rec)
    before = set(sys.modules)  # importlib.import_module raises no audit event: what is new afterwards counts
    try:
        yield rec
    finally:
        _ACTIVE.remove(rec)
        _IMPORTED.setdefault(solver, set()).update(set(sys.modules) - before)


def file_entry(path: str) -> dict[str, Any] | None:
    try:
        st = os.stat(path)
        with open(path, "rb") as fh:
            digest = hashlib.file_digest(fh, "sha256").hexdigest()
    except OSError:
        return None
    return {"sha256": digest, "stat": [st.st_mtime_ns, st.st_size, st.st_ino]}


def _source_module(name: str) -> bool:
    """Whether module `name` counts by its source (not the standard library, not an installed distribution)."""
    top = name.partition(".")[0]
    if top in sys.stdlib_module_names or top in sys.builtin_module_names:
        return False
    module = sys.modules.get(name)
    origin = getattr(getattr(module, "__spec__", None), "origin", None)
    if not isinstance(origin, str) or not os.path.isfile(origin):
        return False
    return not os.path.realpath(origin).startswith(_prefixes())


def dependencies(rec: _Recording, solver_module: str) -> dict[str, Any]:
    """{"files": {path: {"sha256", "stat"}}, "modules": {name: fingerprint}} of a finished recording: what the
    cell's key does not already cover (empty tables when there is nothing)."""
    skip = _prefixes()
    files = {}
    for path in sorted(rec.read - rec.written):
        real = os.path.realpath(path)
        if (real.startswith(skip) or real.endswith(SKIPPED_SUFFIXES) or "__pycache__" in real.split(os.sep)
                or real.startswith(("/proc/", "/sys/", "/dev/")) or not os.path.isfile(real)):
            continue
        entry = file_entry(real)
        if entry is not None:
            files[real] = entry
    covered = set(source_closure(solver_module))
    modules = {name: module_fingerprint(name) for name in sorted(_IMPORTED.get(rec.solver, ()))
               if name not in covered and _source_module(name)}
    return {"files": files, "modules": modules}


def stale(depends: Any) -> str:
    """Why a result recorded with `depends` no longer holds ("" while every file and module is unchanged)."""
    if not isinstance(depends, dict):
        return ""
    for path, entry in (depends.get("files") or {}).items():
        try:
            st = os.stat(path)
        except OSError:
            return f"the file {path} it read is gone"
        if isinstance(entry, dict) and entry.get("stat") == [st.st_mtime_ns, st.st_size, st.st_ino]:
            continue
        now = file_entry(path)
        if now is None or not isinstance(entry, dict) or now["sha256"] != entry.get("sha256"):
            return f"the file {path} it read has changed"
    for name, fingerprint in (depends.get("modules") or {}).items():
        try:
            now = module_fingerprint(name)
        except Exception:  # noqa: BLE001 - a module that cannot be found any more: stale, not a crash
            return f"the module {name} it imported cannot be found"
        if now != fingerprint:
            return f"the module {name} it imported has changed"
    return ""
