"""Studies: a grid of scenes x solvers x resolutions x parameters, as data (TOML).

A study file has a `name`, a `title`, optional `plugins` (modules imported in every process that runs
its cells) and `[[scene]]` tables (scenes built from the shipped building blocks), `[[group]]` tables,
`[[claim]]` tables, `[[calibration]]` tables (`calibspec`) and `[[mutant]]` tables (`mutants`).  Each group
names a scene (with `scene_params`), `solvers`, lists `n` and `refine`, `solver_params`, a `sweep`, and the `analysis`
applied to its cells (the registry in `pcverify.harness.study.analyses`).  The whole file is checked before any
cell is built (`studyfile`).
"""

from __future__ import annotations

import copy
import dataclasses
import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pcverify.harness.study.analyses import ANALYSES
from pcverify.harness.study.calibspec import Calibration, parse_calibrations
from pcverify.harness.study.catalogue import reference_of, register_scene, spec_from_table
from pcverify.harness.study.claims import Claim, parse_claims
from pcverify.harness.study.mutants import Mutant, parse_mutants
from pcverify.harness.study.panels import Panel, parse_panels
from pcverify.harness.study.plugins import load_plugins
from pcverify.harness.study.schema import GROUP, MAX_CELLS, NAME, SCENE, as_list, check_value, row_where
from pcverify.harness.study.shipped import study_path
from pcverify.harness.study.studyfile import (
    check_groups,
    check_study_document,
    read_study_document,
    resolution_names,
    resolutions,
    scene_at,
    solver_params_at,
    solver_params_of,
    target_names,
)
from pcverify.harness.study.tasks import SOLVE, CellTask, ask_supports
from pcverify.scene import Scene, SceneError
from pcverify.solvers.registry import SHIPPED, SolverUnavailable, get_solver, named


@dataclass(frozen=True)
class Cell:
    """One unit of work: a scene value, a solver, a resolution, solver parameters, and the task to run.

    `scene_params` are the parameters the study gave the scene (the scene holds the effective ones);
    `plugins` are imported before the solver is looked up, in whatever process runs the cell, with
    `plugin_folder` (the study file's folder) searched first."""

    group: str
    scene: Scene
    scene_params: tuple[tuple[str, Any], ...]
    solver: str
    n: int
    refine: int
    solver_params: tuple[tuple[str, Any], ...]
    task: CellTask = SOLVE
    serial: bool = False  # timed in the serial pass after a warm-up (part of the cache key)
    plugins: tuple[str, ...] = ()
    plugin_folder: str | None = None
    expressions: tuple[tuple[str, str], ...] = ()  # parameters given as expressions of the resolution ("scene." ...)
    repeats: int = 1  # a timed cell: solved up to this many times in the timed worker, the least CPU time kept
    timed_by: str = ""  # a timed cell: the study whose timed pass times it (part of the key: each study's own pass)

    def describe(self) -> str:
        given = dict(self.expressions)
        shown = [(k, v, given.get(f"scene.{k}")) for k, v in self.scene_params]
        shown += [(k, v, given.get(k)) for k, v in self.solver_params]
        extra = ", ".join(f"{k}={v:.6g} (= {e})" if e else f"{k}={v}" for k, v, e in shown)
        return f"{self.scene.name} / {self.solver} n={self.n} refine={self.refine}" + (f" [{extra}]" if extra else "")


@dataclass(frozen=True)
class Unplanned:
    """A solver a group names whose cells are not planned: its task does not support the group's scene (the
    reason), so each of its `cells` would only be skipped."""

    solver: str
    reason: str
    cells: int


@dataclass
class Group:
    id: str
    title: str
    analysis: str
    cells: list[Cell]
    options: dict[str, Any] = field(default_factory=dict)
    unplanned: list[Unplanned] = field(default_factory=list)


@dataclass
class Study:
    name: str
    title: str
    groups: list[Group]
    claims: list[Claim] = field(default_factory=list)
    plugins: tuple[str, ...] = ()
    path: Path | None = None
    calibrations: list[Calibration] = field(default_factory=list)
    selected: tuple[str, ...] = ()  # `--group` ids: a report of this study merges with the study's full report
    mutants: list[Mutant] = field(default_factory=list)  # its own [[mutant]] tables (`pcverify mutate`)
    shipped_mutants: tuple[str, ...] = ()  # shipped solvers whose catalogued mutants it is run against too
    panels: list[Panel] = field(default_factory=list)  # quantities of several solvers side by side (the report)

    @property
    def plugin_folder(self) -> str | None:
        """Where the study's plugin modules are searched first: the study file's folder."""
        return str(self.path.parent) if self.path is not None else None


def load_study(name_or_path: str, allow_large: bool = False) -> Study:
    """Parse and check a study file (by shipped name or by path): plugins imported, scenes registered,
    every group and claim validated before any cell is built.  A study of more than MAX_CELLS cells is
    refused unless `allow_large` (counted before anything is built)."""
    path = study_path(name_or_path)
    doc = read_study_document(path)
    name = study_name(doc, path)
    count = cell_count(doc, path)
    if count > MAX_CELLS and not allow_large:
        raise SceneError(f"study file {path.name} has {count} cells; allowed: at most {MAX_CELLS} without "
                         "--allow-large")
    normal = check_study_document(doc, path)  # one-line errors for bad fields, before any cell is built
    plugins = tuple(as_list(doc.get("plugins", [])))
    load_plugins(plugins, str(path.resolve().parent))
    for number, table in enumerate(doc.get("scene", []), 1):
        register_scene(spec_from_table(table, row_where(f"study file {path.name}", "scene", number, table, SCENE)),
                       f"study file {path}")
    check_groups(normal, path)
    groups = [_group(g, gi, plugins, str(path.resolve().parent), name) for gi, g in enumerate(normal.get("group", []))]
    by_id = {group.id: g for group, g in zip(groups, normal.get("group", []), strict=True)}

    def levels(table: str) -> Any:
        gid = max((i for i in by_id if table.startswith(f"{i}-")), key=len, default=None)
        return None if gid is None else target_names(by_id[gid])

    claims = parse_claims(normal.get("claim", []), f"study file {path.name}", levels)
    calibrations = parse_calibrations(doc["calibration"], f"study file {path.name}") if "calibration" in doc else []
    require_solvers(sorted({c.solver for g in groups for c in g.cells} | {c.solver for c in calibrations}),
                    f"study file {path.name}")
    mutants = parse_mutants(doc.get("mutant", []), f"study file {path.name}")
    shipped = tuple(as_list(doc.get("shipped_mutants", [])))
    for solver in shipped:
        if solver not in SHIPPED:
            raise SceneError(f"study file {path.name}: shipped_mutants = {solver!r} is not a shipped solver; "
                             f"allowed: one of {', '.join(sorted(SHIPPED))}")
    panels = parse_panels(doc.get("panel", []), f"study file {path.name}", [g.id for g in groups])
    return Study(name, doc.get("title", path.stem), groups, claims, plugins, path.resolve(),
                 calibrations, mutants=mutants, shipped_mutants=shipped, panels=panels)


def study_name(doc: dict[str, Any], path: Path) -> str:
    """The name of the study in `doc` (read from `path`): its `name`, else the file's name without .toml.  It
    names the study's report folder, so it must be a safe folder name (SceneError naming the allowed length
    and characters otherwise)."""
    if "name" in doc:
        return check_value(doc["name"], NAME, f"study file {path.name}")
    return check_value(path.stem, NAME, f"study file {path.name}, which sets no name (so its name is its file name)")


def declared_name(path: Path) -> str:
    """The study name a study file declares, read without importing its plugins or building anything
    (SceneError if the file cannot be read or its name is not valid)."""
    return study_name(read_study_document(path), path)


def require_solvers(names: list[str], where: str) -> None:
    """Every solver a study names must import: a plugin (entry point, module or module:Class) that fails to
    is an error naming it before anything runs, never cells skipped and claims left unjudged.  A shipped solver
    that needs an optional dependency (lammps-bpm) is not refused: its cells are skipped with the reason and its
    claims are not applicable."""
    for name in names:
        if name in SHIPPED:
            continue
        try:
            get_solver(name)
        except SolverUnavailable as exc:
            raise SolverUnavailable(f"{where} names {exc}") from None


def cell_count(doc: dict[str, Any], path: Path) -> int:
    """How many cells the study's groups make (solvers x n x refine x the sweep's combinations), from the
    lengths of the lists alone (of the document as read: this count comes before its check)."""
    total = 0
    for gi, g in enumerate(doc.get("group", []) if isinstance(doc.get("group"), list) else []):
        if not isinstance(g, dict):
            continue
        where = f"{path.name} group {gi + 1}"
        size = 1
        for key in ("solvers", "n", "refine"):
            value = g.get(key, GROUP.field(key).default)
            size *= len(value) if isinstance(value, list) else 1
        sweep = g.get("sweep", {})
        for values in (sweep.values() if isinstance(sweep, dict) else []):
            size *= len(values) if isinstance(values, list) else 1
        if size < 0:
            raise SceneError(f"{where}: cannot count its cells")
        total += size
    return total


def _group(g: dict[str, Any], gi: int, plugins: tuple[str, ...], folder: str, study: str) -> Group:
    gid = g.get("id", f"group{gi + 1}")
    analysis = ANALYSES[g["analysis"]]
    options = {k: v for k, v in g.items() if k not in ("id", "title", "scene", "scene_params", "solvers", "n",
                                                        "refine", "solver_params", "sweep", "analysis", "serial",
                                                        "repeats")}
    task = analysis.task(options)
    scene_params = g.get("scene_params", {})
    scene = scene_at(g["scene"], scene_params, *resolutions(g)[0])[0]
    reference = reference_of(scene.name)
    if analysis.needs_field and (reference is None or reference.field is None):
        raise SceneError(f"group {gid}: analysis {analysis.name} draws err.{options['error']} against "
                         f"the scene's reference field, and scene {scene.name} has none, so its error column would be "
                         "empty; allowed: a scene whose reference gives a field (pcverify scenes NAME says which)")
    sweep = g.get("sweep", {})
    keys = sorted(sweep)
    combos = list(itertools.product(*[as_list(sweep[k]) for k in keys])) or [()]
    cells, unplanned = [], []
    ns, refines = as_list(g["n"]), as_list(g["refine"])
    solvers = []
    for solver in as_list(g["solvers"]):
        why = _unsupported(task, solver, scene)
        if why is None:
            solvers.append(solver)
        else:
            unplanned.append(Unplanned(solver, why, len(ns) * len(refines) * len(combos)))
    at = {(n, r): (scene_at(g["scene"], scene_params, n, r), resolution_names(g["scene"], scene_params, n, r))
          for n, r in resolutions(g)}
    for solver, n, refine, combo in itertools.product(solvers, ns, refines, combos):
        (here, values, scene_expressions), names = at[int(n), int(refine)]
        params = solver_params_of(g.get("solver_params", {}), solver) | dict(zip(keys, combo, strict=True))
        params, solver_expressions = solver_params_at(solver, params, names)
        expressions = {f"scene.{k}": v for k, v in scene_expressions.items()} | solver_expressions
        cells.append(Cell(gid, here if scene_expressions else scene, tuple(sorted(values.items())), solver, int(n),
                          int(refine), tuple(sorted(params.items())), task=task, plugins=plugins,
                          plugin_folder=folder if plugins else None, expressions=tuple(sorted(expressions.items()))))
    if bool(g.get("serial", analysis.serial)):  # a timed cell: its least CPU time of `repeats` solves is its cost
        cells = [dataclasses.replace(c, serial=True, repeats=int(g["repeats"]), timed_by=study) for c in cells]
    return Group(gid, g.get("title", gid), analysis.name, cells, options, unplanned)


def _unsupported(task: CellTask, solver_name: str, scene: Scene) -> str | None:
    """Why `solver_name`'s cells of a group on `scene` would all be skipped (its task does not support the
    scene), or None: planned.  A solver that cannot be loaded, or whose `supports` raises or answers something
    other than (bool, text), is planned: its cells then fail (or skip) with the reason, one by one."""
    try:
        ok, reason = ask_supports(task, named(get_solver(solver_name), solver_name), copy.deepcopy(scene))
    except KeyboardInterrupt:
        raise
    except BaseException:  # noqa: BLE001 - a plugin's failure belongs to its cells, which report it
        return None
    return None if ok else (reason or "the solver does not support this scene")
