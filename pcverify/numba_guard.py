"""numba's on-disk cache guarded so that compiled code never outlives an edit of any source it came from.

numba's `cache=True` checks only the file that defines a jitted function, not the modules it calls into,
so after an edit of a helper module the old machine code was loaded and run.  Each of numba's cache
locators is wrapped (same cache folder and file names) so that its source stamp also holds the source
closure fingerprint of the function's module (pcverify.fingerprint); numba treats another stamp as a miss
and recompiles.  `import pcverify` installs it without importing numba: when numba's caching module loads.
"""

from __future__ import annotations

import os
import sys
import warnings
from importlib.machinery import ModuleSpec
from types import ModuleType
from typing import Any

from pcverify.fingerprint import module_fingerprint

CACHING = "numba.core.caching"


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


class _WhenNumbaCachingLoads:
    """A meta-path finder that finds nothing itself: it lets numba's caching module load as usual and then
    guards it, and steps aside."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> ModuleSpec | None:
        if name != CACHING:
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

        def exec_and_guard(module: ModuleType) -> None:
            exec_module(module)
            if self in sys.meta_path:
                sys.meta_path.remove(self)
            guard(module)

        spec.loader.exec_module = exec_and_guard
        return spec


def guard_numba_cache() -> None:
    """Guard numba's cache now if numba's caching module is loaded, else as soon as it is."""
    caching = sys.modules.get(CACHING)
    if caching is not None:
        guard(caching)
    elif not any(isinstance(f, _WhenNumbaCachingLoads) for f in sys.meta_path):
        sys.meta_path.insert(0, _WhenNumbaCachingLoads())
