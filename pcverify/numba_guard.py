"""numba's on-disk cache guarded so that compiled code never outlives an edit of any source it came from, and
compiled once when several processes need it at the same time.

numba's `cache=True` checks only the file that defines a jitted function, not the modules it calls into.  Each
of numba's cache locators is therefore wrapped so that its source stamp also holds the source closure
fingerprint of the function's module (pcverify.fingerprint): another stamp is a miss, and numba recompiles.
`import pcverify` installs it, without importing numba, when numba's caching module loads.  A compilation of
one signature holds an exclusive file lock beside its cache entry, so a study's workers, started alike, do not
all compile the same kernels (20 s for an MCA contact kernel): a second process waits, then loads what the
first saved; callees lock inside their callers, in call-graph order, so no two processes wait on each other.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any

from pcverify.fingerprint import module_fingerprint

try:
    import fcntl
except ImportError:  # not POSIX: each process compiles on its own, as numba does
    fcntl = None  # type: ignore[assignment]

CACHING = "numba.core.caching"
DISPATCHER = "numba.core.dispatcher"


class ClosureStampedLocator:
    """A numba cache locator around one of numba's own: its cache path and disambiguator, and as source
    stamp its stamp together with the fingerprint of the jitted function's module.  Subclassed per wrapped
    class (`inner`), since numba asks a locator class for `from_function`."""

    inner: Any = None

    def __init__(self, locator: Any, module: str) -> None:
        self._locator = locator
        self._module = module

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> ClosureStampedLocator | None:
        locator = cls.inner.from_function(py_func, py_file)
        return None if locator is None else cls(locator, py_func.__module__)

    def ensure_cache_path(self) -> None:
        self._locator.ensure_cache_path()

    def get_cache_path(self) -> str:
        return self._locator.get_cache_path()

    def get_disambiguator(self) -> str:
        return self._locator.get_disambiguator()

    def get_source_stamp(self) -> tuple[Any, str]:
        return self._locator.get_source_stamp(), module_fingerprint(self._module)


def _stamped(locator_class: type) -> type:
    if issubclass(locator_class, ClosureStampedLocator):
        return locator_class
    return type(f"ClosureStamped{locator_class.__name__}", (ClosureStampedLocator,), {"inner": locator_class})


def guard(caching: ModuleType) -> None:
    """Wrap the cache locators of numba's caching module (idempotent); an unknown numba layout is an error,
    never a silently stale cache."""
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    if not isinstance(getattr(impl, "_locator_classes", None), list):
        raise ImportError("pcverify cannot guard numba's cache against stale compiled code: numba.core.caching has "
                          "no CacheImpl._locator_classes list (a numba version pcverify does not know)")
    todo = [impl]
    while todo:
        cls = todo.pop()
        todo.extend(cls.__subclasses__())
        if "_locator_classes" in vars(cls):
            cls._locator_classes = [_stamped(c) for c in cls._locator_classes]
    if os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES"):
        warnings.warn("NUMBA_CACHE_LOCATOR_CLASSES is set: numba uses those cache locators, and pcverify cannot "
                      "guard them against compiled code older than the sources it calls", stacklevel=2)


def _lock_path(dispatcher: Any, sig: Any) -> str | None:
    """The lock file of one signature of a cached function (beside its cache index), or None: not cached."""
    cache_file = getattr(getattr(dispatcher, "_cache", None), "_cache_file", None)  # NullCache has none
    folder, index = getattr(cache_file, "_cache_path", None), getattr(cache_file, "_index_name", None)
    if fcntl is None or not isinstance(folder, str) or not isinstance(index, str):
        return None
    return os.path.join(folder, f"{index}.{hashlib.sha256(str(sig).encode()).hexdigest()[:16]}.lock")


def _compiled_once(compile: Any) -> Any:
    """Dispatcher.compile under the file lock of the signature (a cache hit while waiting is a load)."""
    if getattr(compile, "pcverify_locked", False):
        return compile

    @functools.wraps(compile)
    def locked(self: Any, sig: Any) -> Any:
        path = _lock_path(self, sig)
        if path is None:
            return compile(self, sig)
        try:
            os.makedirs(os.path.dirname(path), exist_ok=True)
            handle = open(path, "a")  # noqa: SIM115 - held for the compilation, closed below
        except OSError:  # a read-only cache folder: numba compiles in memory, each process on its own
            return compile(self, sig)
        try:
            fcntl.flock(handle, fcntl.LOCK_EX)
            return compile(self, sig)
        finally:
            handle.close()  # releases the lock

    locked.pcverify_locked = True
    return locked


def lock_compilation(dispatcher_module: ModuleType) -> None:
    """Compile each cached function's signature once across processes (idempotent; nothing to do in a numba
    without Dispatcher.compile)."""
    cls = getattr(dispatcher_module, "Dispatcher", None)
    if cls is not None and callable(getattr(cls, "compile", None)):
        cls.compile = _compiled_once(cls.compile)


class _WhenNumbaCachingLoads:
    """A meta-path finder that finds nothing itself: it lets numba's caching and dispatcher modules load as usual
    and then guards them, and steps aside once both are done."""

    def __init__(self) -> None:
        self.pending = {CACHING: guard, DISPATCHER: lock_compilation}

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if name not in self.pending:
            return None
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            if finder is self or find is None:
                continue
            spec = find(name, path, target)
            if spec is not None and spec.loader is not None:
                break
        else:
            return None
        exec_module = spec.loader.exec_module

        after = self.pending.pop(name)

        def exec_and_guard(module: ModuleType) -> None:
            exec_module(module)
            if not self.pending and self in sys.meta_path:
                sys.meta_path.remove(self)
            after(module)

        spec.loader.exec_module = exec_and_guard
        return spec


def guard_numba_cache() -> None:
    """Guard numba's cache and lock its compilations now where numba's modules are loaded, else as soon as they
    are."""
    if any(isinstance(f, _WhenNumbaCachingLoads) for f in sys.meta_path):
        return
    finder = _WhenNumbaCachingLoads()
    for name in list(finder.pending):
        if name in sys.modules:
            finder.pending.pop(name)(sys.modules[name])
    if finder.pending:
        sys.meta_path.insert(0, finder)
