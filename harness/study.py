"""Studies: a grid of scenes x solvers x resolutions x parameters, as data (TOML).

A study file has a `name`, a `title` and `[[group]]` tables; each group names a scene
(with `scene_params`), `solvers`, lists `n` and `refine`, `solver_params`, and the
`analysis` applied to its cells (see harness.analysis).  Every cell is cached by
content hash; an interrupted study resumes where it stopped.
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import json
import time
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from tqdm import tqdm

from pcverify.harness.cache import Cache, cell_key
from pcverify.harness.catalogue import make_scene
from pcverify.harness.interrupt import check_interrupted, ignore_sigint_in_worker
from pcverify.harness.scene import SceneError
from pcverify.harness.studyfile import check_study_document, read_study_document
from pcverify.harness.verdict import parse_claims

ANALYSES = ("convergence", "timing", "table", "work-precision", "stability")
SERIAL_ANALYSES = ("timing", "work-precision")  # their wall times are compared: serial pass after a warm-up


@dataclass(frozen=True)
class Cell:
    """One solve: scene (by name and params), solver, resolution and solver parameters."""

    group: str
    scene: str
    scene_params: tuple[tuple[str, Any], ...]
    solver: str
    n: int
    refine: int
    solver_params: tuple[tuple[str, Any], ...]
    serial: bool = False  # timed in the serial pass after a warm-up (part of the cache key)
    probe: str = ""  # stability cells: "limit" or "map", run by a harness.stability probe, not by solve()

    def describe(self) -> str:
        extra = ", ".join(f"{k}={v}" for k, v in self.scene_params + self.solver_params)
        return f"{self.scene} / {self.solver} n={self.n} refine={self.refine}" + (f" [{extra}]" if extra else "")


@dataclass
class Group:
    id: str
    title: str
    analysis: str
    cells: list[Cell]
    options: dict[str, Any] = field(default_factory=dict)


@dataclass
class Study:
    name: str
    title: str
    groups: list[Group]
    claims: list[Any] = field(default_factory=list)  # harness.verdict.Claim


def study_files() -> dict[str, Path]:
    """The study files shipped with the package, by name."""
    folder = resources.files("pcverify.harness") / "studies"
    return {Path(str(p)).stem: Path(str(p)) for p in folder.iterdir() if str(p).endswith(".toml")}


def _list(value: Any, what: str, path: str) -> list[Any]:
    items = value if isinstance(value, list) else [value]
    if not items:
        raise SceneError(f"{path}: {what} is empty; allowed: a value or a non-empty list")
    return items


def _solver_params(table: dict[str, Any], solver: str) -> dict[str, Any]:
    """Shared solver parameters plus those under a sub-table named after `solver` (e.g. macromolecule = {...})."""
    shared = {k: v for k, v in table.items() if not isinstance(v, dict)}
    return shared | dict(table.get(solver, {}))


def load_study(name_or_path: str) -> Study:
    """Parse and validate a study file (by shipped name or by path)."""
    shipped = study_files()
    path = shipped.get(name_or_path, Path(name_or_path))
    if not path.exists():
        raise SceneError(f"study={name_or_path!r} is unknown; allowed: one of {', '.join(sorted(shipped))} "
                         "or a path to a .toml file")
    doc = read_study_document(path)
    check_study_document(doc, path, ANALYSES)  # one-line errors for bad fields, before any cell is built
    groups = []
    for gi, g in enumerate(doc.get("group", [])):
        where = f"{path.name} group {gi + 1}"
        gid = g.get("id", f"group{gi + 1}")
        analysis = g.get("analysis", "table")
        if analysis not in ANALYSES:
            raise SceneError(f"{where}: analysis={analysis!r} is unknown; allowed: one of {', '.join(ANALYSES)}")
        if "scene" not in g:
            raise SceneError(f"{where}: scene is missing")
        scene_params = g.get("scene_params", {})
        probe = g.get("probe", "limit") if analysis == "stability" else ""
        if probe and probe not in ("limit", "map"):
            raise SceneError(f"{where}: probe={probe!r} is unknown; allowed: one of limit, map")
        make_scene(g["scene"], **scene_params)  # validates names and values now, not mid-study
        sweep = g.get("sweep", {})
        keys = sorted(sweep)
        combos = list(itertools.product(*[_list(sweep[k], f"sweep.{k}", where) for k in keys])) or [()]
        cells = []
        for solver, n, refine, combo in itertools.product(
            _list(g.get("solvers", []), "solvers", where), _list(g.get("n", [4]), "n", where),
            _list(g.get("refine", [1]), "refine", where), combos,
        ):
            params = _solver_params(g.get("solver_params", {}), solver) | dict(zip(keys, combo, strict=True))
            cells.append(Cell(gid, g["scene"], tuple(sorted(scene_params.items())), solver, int(n), int(refine),
                              tuple(sorted(params.items())), probe=probe))
        serial = bool(g.get("serial", analysis in SERIAL_ANALYSES))
        if serial:
            cells = [dataclasses.replace(c, serial=True) for c in cells]
        options = {k: v for k, v in g.items() if k not in ("id", "title", "scene", "scene_params", "solvers", "n",
                                                            "refine", "solver_params", "sweep", "analysis", "serial")}
        groups.append(Group(gid, g.get("title", gid), analysis, cells, options))
    if not groups:
        raise SceneError(f"study file {path}: no [[group]] tables")
    claims = parse_claims(doc.get("claim", []), path.name)
    return Study(doc.get("name", path.stem), doc.get("title", path.stem), groups, claims)


def cell_identity(cell: Cell) -> tuple[dict[str, Any], Any, Any, str | None]:
    """(key payload, scene, solver, skip reason) for a cell; the payload includes the solver's code version."""
    from pcverify.harness.scene import Resolution
    from pcverify.solvers.protocol import effective_params
    from pcverify.solvers.registry import SolverUnavailable, get_solver

    scene = make_scene(cell.scene, **dict(cell.scene_params))
    resolution = Resolution(cell.n, cell.refine)
    if cell.probe:
        return _probe_identity(cell, scene)
    try:
        solver = get_solver(cell.solver)
    except SolverUnavailable as exc:
        payload = {"scene": scene.content_hash(), "solver": cell.solver, "unavailable": True, "n": cell.n,
                   "refine": cell.refine, "params": dict(cell.solver_params)}
        return payload, scene, None, str(exc)
    params = effective_params(solver, dict(cell.solver_params))
    payload = {"scene": scene.content_hash(), "solver": solver.name, "version": solver.version, "n": resolution.n,
               "refine": resolution.refine, "params": params}
    if cell.serial:
        payload["timing"] = "serial-after-warm-up"
    ok, reason = solver.supports(scene)
    return payload, scene, solver, None if ok else reason


def _probe_identity(cell: Cell, scene: Any) -> tuple[dict[str, Any], Any, Any, str | None]:
    """cell_identity of a stability cell: the probe stands in for the solver (skipped if it has none)."""
    from pcverify.harness.stability import ProbeUnavailable, get_probe, split_params

    payload = {"scene": scene.content_hash(), "solver": cell.solver, "probe": cell.probe, "n": cell.n,
               "refine": cell.refine, "params": dict(cell.solver_params)}
    try:
        probe = get_probe(cell.solver)
    except ProbeUnavailable as exc:
        return payload | {"unavailable": True}, scene, None, str(exc)
    split_params(dict(cell.solver_params))  # validates the probe's own keys now, not mid-study
    ok, reason = probe.supports(scene)
    return payload | {"version": probe.version}, scene, probe, None if ok else reason


def run_cell(cell: Cell) -> dict[str, Any]:
    """Solve one cell and return its JSON-ready result (skips and failures are results too)."""
    from pcverify.harness.scene import Resolution

    payload, scene, solver, skip = cell_identity(cell)
    base = {"group": cell.group, "scene": cell.scene, "solver": cell.solver, "n": cell.n, "refine": cell.refine,
            "scene_params": dict(cell.scene_params), "solver_params": dict(cell.solver_params)}
    if skip is not None:
        return base | {"status": "skipped", "reason": skip}
    if cell.probe:
        from pcverify.harness.stability import run_probe_cell

        try:
            return base | run_probe_cell(cell.probe, solver, scene, cell.n, dict(cell.solver_params))
        except (SceneError, ValueError, ArithmeticError) as exc:
            return base | {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
    try:
        solution = solver.solve(scene, Resolution(cell.n, cell.refine), **dict(cell.solver_params))
    except (SceneError, ValueError, ArithmeticError, MemoryError) as exc:
        return base | {"status": "failed", "reason": f"{type(exc).__name__}: {exc}"}
    return base | solution.to_dict() | {"solver_kind": solver.kind}


def _indexed(i: int, cell: Cell) -> tuple[int, dict[str, Any]]:
    ignore_sigint_in_worker()
    return i, run_cell(cell)


def _parallel(cells: list[Cell], todo: list[int], jobs: int, scheduler: str | None):
    """(index, result) pairs in completion order: joblib on local cores, or a Dask cluster at `scheduler`."""
    if scheduler:
        try:
            from distributed import Client, as_completed
        except ImportError:
            raise SceneError("--scheduler needs the optional dependency dask[distributed]; allowed: install it with "
                             "pip install 'pcverify[dask]', or run without --scheduler") from None
        try:
            client = Client(scheduler, timeout="5s")
        except OSError as exc:
            raise SceneError(f"scheduler={scheduler!r} is not reachable ({exc}); allowed: the address of a running "
                             "Dask scheduler, e.g. tcp://host:8786") from None
        with client:
            futures = [client.submit(_indexed, i, cells[i], pure=False) for i in todo]
            for fut in as_completed(futures):
                yield fut.result()
        return
    import warnings

    from joblib import Parallel, delayed

    # loky replaces a worker whose memory grew (numba, FiPy caches) and says so; the cell is rerun, nothing lost
    warnings.filterwarnings("ignore", message="A worker stopped while some jobs", category=UserWarning)
    yield from Parallel(n_jobs=jobs, return_as="generator_unordered")(delayed(_indexed)(i, cells[i]) for i in todo)


def _warm_up(cells: list[Cell]) -> None:
    """Solve the cheapest cell of each solver once, uncached, so compilation stays out of the timings."""
    cheapest: dict[str, Cell] = {}
    for c in cells:
        if c.solver not in cheapest or (c.n, c.refine) < (cheapest[c.solver].n, cheapest[c.solver].refine):
            cheapest[c.solver] = c
    for c in cheapest.values():
        run_cell(c)


def execute(study: Study, cache: Cache, dry_run: bool = False, jobs: int = 1, progress: bool = True,
            scheduler: str | None = None) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Run every cell not yet cached; return all results in cell order and the counts.

    Cells of timing groups run last, serially in this process, after a warm-up solve per solver;
    the others run in parallel (joblib with `jobs` > 1, or a Dask cluster at `scheduler`).
    Each finished cell is written to the cache at once, so an interrupted study loses nothing.
    """
    cells = [c for g in study.groups for c in g.cells]
    identities = [cell_identity(c) for c in cells]
    keys = [cell_key(ident[0]) for ident in identities]
    results: list[dict[str, Any] | None] = []
    counts = {"cells": len(cells), "cached": 0, "done": 0, "failed": 0, "corrupt": 0}
    todo = []
    for i, key in enumerate(keys):
        entry, state = cache.load(key)
        entry = as_cell(entry, cells[i])
        if state.startswith("corrupt"):
            counts["corrupt"] += 1
            tqdm.write(f"cache entry {key} ({cells[i].describe()}) is {state}; recomputing")
        if entry is not None:
            counts["cached"] += 1
        else:
            todo.append(i)
        results.append(entry)
    if dry_run:
        for i, c in enumerate(cells):
            skip = identities[i][3]
            state = "cached" if results[i] is not None else ("skip" if skip else "to run")
            print(f"{state:<8} {keys[i]}  {c.describe()}" + (f"  ({skip})" if skip and state == "skip" else ""))
        return [r for r in results if r is not None], counts
    bar = tqdm(total=len(cells), initial=counts["cached"], desc=study.name, unit="cell", disable=not progress,
               dynamic_ncols=True)

    first: dict[str, int] = {}
    same: dict[int, list[int]] = {}  # cells of other groups with the same key: solved once, shared
    for i in todo:
        if keys[i] in first:
            same[first[keys[i]]].append(i)
        else:
            first[keys[i]] = i
            same[i] = []
    todo = [i for i in todo if first[keys[i]] == i]

    def finish(i: int, res: dict[str, Any]) -> None:
        res["cache_key"] = keys[i]
        cache.store(keys[i], res)
        results[i] = res
        counts["failed" if res.get("status") == "failed" else "done"] += 1
        for j in same[i]:
            results[j] = as_cell(res, cells[j])
            counts["cached"] += 1
        bar.set_postfix(done=counts["done"], cached=counts["cached"], failed=counts["failed"])
        bar.update(1 + len(same[i]))
        check_interrupted()  # a Ctrl-C that a library swallowed stops the study here, this cell stored

    free = [i for i in todo if not cells[i].serial]
    timed = [i for i in todo if cells[i].serial and identities[i][3] is None]
    timed_skips = [i for i in todo if cells[i].serial and identities[i][3] is not None]
    if (jobs > 1 or scheduler) and len(free) > 1:
        for i, res in _parallel(cells, free, jobs, scheduler):
            finish(i, res)
    else:
        timed_skips = free + timed_skips
    for i in timed_skips:
        bar.set_description(f"{study.name}: {cells[i].describe()}"[:70])
        finish(i, run_cell(cells[i]))
    if timed:
        bar.set_description(f"{study.name}: warm-up before the timed serial pass")
        _warm_up([cells[i] for i in timed])
    for i in timed:
        bar.set_description(f"{study.name}: timed {cells[i].describe()}"[:70])
        finish(i, run_cell(cells[i]) | {"timing": "serial after warm-up"})
    bar.close()
    return [r for r in results if r is not None], counts


def cached_results(study: Study, cache: Cache) -> list[dict[str, Any]]:
    """The results of a study's cells that are in the cache (corrupt or missing ones left out)."""
    cells = [c for g in study.groups for c in g.cells]
    entries = (as_cell(cache.load(cell_key(cell_identity(c)[0]))[0], c) for c in cells)
    return [e for e in entries if e is not None]


def as_cell(entry: dict[str, Any] | None, cell: Cell) -> dict[str, Any] | None:
    """A cached result seen as the result of `cell`: the same solve may have been cached by another group
    or study (same content key), so the identity fields are the cell's own, not those of its first run."""
    if entry is None:
        return None
    return entry | {"group": cell.group, "scene": cell.scene, "solver": cell.solver, "n": cell.n,
                    "refine": cell.refine, "scene_params": dict(cell.scene_params),
                    "solver_params": dict(cell.solver_params)}


def run_study_cli(args: argparse.Namespace) -> int:
    """`pcverify study NAME`: run (or dry-run) one study, or all shipped ones for `default`."""
    from pcverify.harness.report import write_index, write_study_report

    names = sorted(study_files()) if args.name == "default" else [args.name]
    studies = [load_study(n) for n in names]  # validate all before running any
    out = Path(args.out)
    cache = Cache(args.cache or out / "cache")
    summary = []
    for study in studies:
        t0 = time.perf_counter()
        results, counts = execute(study, cache, dry_run=args.dry_run, jobs=args.jobs, progress=not args.json,
                                  scheduler=getattr(args, "scheduler", None))
        if args.dry_run:
            summary.append({"study": study.name, **counts})
            continue
        write_study_report(study, results, out)
        summary.append({"study": study.name, **counts, "wall_s": round(time.perf_counter() - t0, 3)})
        if not args.json:
            print(f"{study.name}: {counts['cells']} cells, {counts['cached']} cached, {counts['done']} run, "
                  f"{counts['failed']} failed, {counts['corrupt']} corrupt entries recomputed "
                  f"-> {out / study.name}/")
    if not args.dry_run:
        index = write_index(out)
        if not args.json:
            print(f"report: {index}")
    if args.json:
        print(json.dumps(summary))
    return 0
