"""Plugin modules: a study file's `plugins = ["some.module", ...]`, imported in every process that runs
its cells.  A plugin module makes its solvers and scenes known by defining them: every Solver class
defined in the module (a class with the protocol's name, kind, parameters, supports and solve) is
registered under its name, every SceneSpec it holds under the spec's name."""

from __future__ import annotations

import importlib
from collections.abc import Iterable
from functools import cache

from pcverify.harness.study.catalogue import register_scene
from pcverify.scene import SceneError, SceneSpec, shown
from pcverify.solvers.registry import MODULE, is_solver_class, register_solver, search_first


class PluginError(SceneError):
    """A plugin that cannot be imported or that clashes with another (one line, names it)."""


def load_plugins(modules: Iterable[str], folder: str | None = None) -> None:
    """Import each plugin module once per process and register what it defines; `folder` (the study file's
    folder) is searched first, so a module beside the study file needs no PYTHONPATH."""
    modules = tuple(modules)
    if folder and modules:
        search_first(folder)
    for name in modules:
        _load(name)


@cache
def _load(name: str) -> None:
    if not isinstance(name, str) or not MODULE.match(name):
        raise PluginError(f"plugins entry {shown(name)} is not valid; allowed: a dotted module name")
    try:
        module = importlib.import_module(name)
    except (Exception, SystemExit) as exc:  # noqa: BLE001 - any import-time error of the plugin, shown as one line
        raise PluginError(f"plugin {name!r} failed to import: {type(exc).__name__}: {' '.join(str(exc).split())}"
                          ) from None
    origin = f"plugin module {name}"
    found = 0
    for value in vars(module).values():
        if is_solver_class(value) and value.__module__ == module.__name__:
            register_solver(value, origin)
            found += 1
        elif isinstance(value, SceneSpec):
            register_scene(value, origin)
            found += 1
    if not found:
        raise PluginError(f"plugin {name!r} defines no Solver class and no SceneSpec; allowed: a module that defines "
                          "at least one")
