"""Calibration as study data: the `[[calibration]]` tables of a study file, read and checked.

A calibration names a solver, its fixed parameters, the free parameters with bounds (`log = true` to
search in log space), the calibration cells (scene, n, metric, reference) the objective is measured on,
and the validation cells held out from it.  A calibration whose calibration and validation cells
overlap (the same metric of the same run as the solver sees it: what it reads of the scene, the resolution,
and refine only for a solver that uses it) is refused with the cells named: a number the parameters were
fitted to is not a validation.  Another metric of a calibration cell's run
(torsion beside the bending frequency it was fitted to) is allowed, and the validation table says that
it shares the run.  `pcverify.harness.calibration`
runs what this module describes; everything here is checked before any cell runs, with one-line
SceneErrors like the other study-file errors: also a budget below the number of calibration cells (it
would evaluate nothing) and replicas that name a free parameter (the optimum would override them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from pcverify.harness.catalogue import make_scene
from pcverify.harness.studyfile import safe_name
from pcverify.scene import Scene, SceneError, shown
from pcverify.solvers.protocol import effective_params, uses_refine
from pcverify.solvers.registry import SolverUnavailable, get_solver

DESIGNS = ("sobol", "lhs")
ERRORS = ("relative", "absolute")
FIELD_KINDS = (".l2", ".linf")  # metrics <sample set>.l2 / .linf are field errors against the analytic solution

CALIBRATION_KEYS = {
    "id": "calibration id (letters, digits, . _ -)", "title": "text", "solver": "a solver name",
    "solver_params": "{ name = value }: fixed parameters of every run", "parameter": "[[calibration.parameter]] tables",
    "calibrate": "[[calibration.calibrate]] tables", "validate": "[[calibration.validate]] tables",
    "budget": "integer: solver runs of the search (design + local search)", "design": "sobol or lhs",
    "design_points": "integer: points of the space-filling design", "starts": "integer: local searches",
    "seed": "integer: seed of the design", "replicas": "{ parameter = [values] }: runs at the optimum that "
    "measure the objective's noise", "noise_factor": "number: the band is best + noise_factor * noise",
    "noise_floor": "number: smallest band (objective units)", "sensitivity_step": "number in (0, 0.5]: step "
    "of the one-at-a-time sensitivity as a fraction of each parameter's (log) range",
    "tolerance": "number: the validation error below which a held-out cell counts as matched",
}
PARAMETER_KEYS = {"name": "a solver parameter", "low": "number", "high": "number", "log": "true/false"}
CELL_KEYS = {"scene": "a scene name", "scene_params": "{ name = value }", "n": "integer or list of integers",
             "refine": "integer", "metric": "a summary quantity or <samples>.l2 / .linf",
             "reference": "analytic, or { solver, n, refine, solver_params } (a list of >= 3 refine: Richardson)",
             "error": "relative or absolute (scalar metrics; default relative)"}
REFERENCE_KEYS = {"solver": "a solver name", "n": "integer (default: the cell's n)",
                  "refine": "integer or list of >= 3 integers", "solver_params": "{ name = value }"}


@dataclass(frozen=True)
class FreeParam:
    """One free parameter: its bounds and whether it is searched in log space."""

    name: str
    low: float
    high: float
    log: bool = False

    def to_unit(self, value: float) -> float:
        """The value as a coordinate in [0, 1] (log-scaled if `log`)."""
        if self.log:
            return (math.log(value) - math.log(self.low)) / (math.log(self.high) - math.log(self.low))
        return (value - self.low) / (self.high - self.low)

    def from_unit(self, u: float) -> float:
        """The value at coordinate u in [0, 1], rounded to 10 significant digits (stable cache keys)."""
        u = min(max(float(u), 0.0), 1.0)
        v = (math.exp(math.log(self.low) + u * (math.log(self.high) - math.log(self.low))) if self.log
             else self.low + u * (self.high - self.low))
        return float(f"{min(max(v, self.low), self.high):.10g}")


@dataclass(frozen=True)
class Reference:
    """What a scalar metric is compared with: a continuum solver's value on the same scene, at one grid or
    Richardson-extrapolated over three or more refinements.  `n` None: the cell's own n."""

    solver: str
    n: int | None
    refine: tuple[int, ...]
    solver_params: tuple[tuple[str, Any], ...] = ()

    def describe(self) -> str:
        grid = f"n={self.n}" if self.n is not None else "same n"
        if len(self.refine) >= 3:
            return f"{self.solver} {grid} refine {list(self.refine)} (Richardson-extrapolated)"
        return f"{self.solver} {grid} refine {self.refine[0]} (same lattice)" if self.n is None else \
            f"{self.solver} {grid} refine {self.refine[0]}"


@dataclass(frozen=True)
class CalibCell:
    """A cell of a calibration: where the error is measured, which metric, against what."""

    scene: Scene
    scene_params: tuple[tuple[str, Any], ...]
    n: int
    refine: int
    metric: str
    reference: Reference | None  # None: the scene's analytic solution
    error: str = "relative"
    refine_read: bool = True  # whether the calibrated solver reads refine (`protocol.uses_refine`)

    def key(self) -> tuple[str, int, int]:
        """The run this cell measures, as the solver sees it: what it reads of the scene
        (`Scene.solver_input_hash`: not the scene's name, recipe, or the times a steady scene ignores), n, and
        refine when the solver uses it (else 1)."""
        return (self.scene.solver_input_hash(), self.n, self.refine if self.refine_read else 1)

    def measure(self) -> tuple[str, int, int, str]:
        """Identity for the overlap guard: the run and the metric measured on it."""
        return (*self.key(), self.metric)

    def describe(self) -> str:
        extra = ", ".join(f"{k}={v}" for k, v in self.scene_params)
        return f"{self.scene.name}{' [' + extra + ']' if extra else ''} n={self.n}" + (
            f" refine={self.refine}" if self.refine != 1 else "")

    def reference_label(self) -> str:
        return "analytic" if self.reference is None else self.reference.describe()


@dataclass(frozen=True)
class Calibration:
    """One `[[calibration]]` table, checked."""

    id: str
    title: str
    solver: str
    solver_params: tuple[tuple[str, Any], ...]
    parameters: tuple[FreeParam, ...]
    calibrate: tuple[CalibCell, ...]
    validate: tuple[CalibCell, ...]
    budget: int = 32
    design: str = "sobol"
    design_points: int = 16
    starts: int = 1
    seed: int = 0
    replicas: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    noise_factor: float = 2.0
    noise_floor: float = 0.0
    sensitivity_step: float = 0.1
    tolerance: float = math.nan
    defaults: dict[str, Any] = field(default_factory=dict)  # the solver's declared values of the free parameters


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _integer(value: Any, what: str, where: str, low: int, high: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SceneError(f"{where}: {what}={shown(value)} is not valid; allowed: integer in [{low}, {high}]")
    return value


def _table(value: Any, what: str, where: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise SceneError(f"{where}: {what}={shown(value)} is not valid; allowed: a table {{ key = value, ... }}")
    return value


def _unknown(item: dict[str, Any], allowed: dict[str, str], what: str, where: str) -> None:
    unknown = sorted(set(item) - set(allowed))
    if unknown:
        raise SceneError(f"{where}: {unknown[0]} is not a field of {what}; allowed: {', '.join(allowed)}")


def _solver_params_ok(solver: Any, params: dict[str, Any], where: str) -> dict[str, Any]:
    try:
        return effective_params(solver, params)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _parameter(item: Any, solver: Any, fixed: dict[str, Any], where: str) -> FreeParam:
    item = _table(item, "parameter", where)
    _unknown(item, PARAMETER_KEYS, "a [[calibration.parameter]]", where)
    name = item.get("name")
    known = [p.name for p in solver.parameters]
    if not isinstance(name, str) or name not in known:
        raise SceneError(f"{where}: name={shown(name)} is not a parameter of solver {solver.name!r}; allowed: one "
                         f"of {', '.join(known)}")
    if name in fixed:
        raise SceneError(f"{where}: {name} is both free and fixed (solver_params); allowed: one of the two")
    low, high, log = item.get("low"), item.get("high"), item.get("log", False)
    if not (_number(low) and _number(high) and low < high):
        raise SceneError(f"{where}: low={shown(low)}, high={shown(high)} are not valid; allowed: numbers with "
                         "low < high")
    if not isinstance(log, bool):
        raise SceneError(f"{where}: log={shown(log)} is not valid; allowed: true/false")
    if log and low <= 0:
        raise SceneError(f"{where}: low={shown(low)} is not valid with log = true; allowed: low > 0")
    for bound in (low, high):  # both bounds inside the solver's declared range
        _solver_params_ok(solver, fixed | {name: float(bound)}, f"{where} ({name} bound)")
    return FreeParam(name, float(low), float(high), log)


def _reference(value: Any, where: str) -> Reference | None:
    if value == "analytic":
        return None
    table = _table(value, "reference", where)
    _unknown(table, REFERENCE_KEYS, "a reference", where)
    solver = table.get("solver")
    if not isinstance(solver, str):
        raise SceneError(f"{where}: reference solver={shown(solver)} is not valid; allowed: a solver name")
    n = table.get("n")
    if n is not None:
        n = _integer(n, "reference n", where, 2, 1000)
    refine = table.get("refine", 1)
    refines = refine if isinstance(refine, list) else [refine]
    refines = [_integer(r, "reference refine", where, 1, 1000) for r in refines]
    if len(refines) == 2 or len(set(refines)) != len(refines):
        raise SceneError(f"{where}: reference refine={shown(refine)} is not valid; allowed: one integer, or a list of "
                         "three or more different integers (Richardson)")
    params = _table(table.get("solver_params", {}), "reference solver_params", where)
    return Reference(solver, n, tuple(refines), tuple(sorted(params.items())))


def _cells(item: Any, where: str, refine_read: bool) -> list[CalibCell]:
    item = _table(item, "cell", where)
    _unknown(item, CELL_KEYS, "a calibration or validation cell", where)
    name = item.get("scene")
    if not isinstance(name, str):
        raise SceneError(f"{where}: scene={shown(name)} is not valid; allowed: a scene name (see `pcverify scenes`)")
    scene_params = _table(item.get("scene_params", {}), "scene_params", where)
    try:
        scene = make_scene(name, **scene_params)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    ns = item.get("n", 4)
    ns = [_integer(n, "n", where, 2, 1000) for n in (ns if isinstance(ns, list) else [ns])]
    if not ns:
        raise SceneError(f"{where}: n is empty; allowed: an integer or a non-empty list")
    refine = _integer(item.get("refine", 1), "refine", where, 1, 1000)
    metric = item.get("metric")
    if not isinstance(metric, str) or not metric:
        raise SceneError(f"{where}: metric={shown(metric)} is not valid; allowed: {CELL_KEYS['metric']}")
    if "reference" not in item:
        raise SceneError(f"{where}: reference is missing; allowed: {CELL_KEYS['reference']}")
    reference = _reference(item["reference"], where)
    if metric.endswith(FIELD_KINDS) and reference is not None:
        raise SceneError(f"{where}: metric={metric!r} is a field error against the analytic solution; allowed: "
                         "reference = \"analytic\" with it")
    if reference is None and not metric.endswith(FIELD_KINDS):
        raise SceneError(f"{where}: metric={metric!r} with reference = \"analytic\"; allowed: a field error "
                         "<samples>.l2 or .linf (a scalar metric needs a solver reference)")
    error = item.get("error", "relative")
    if error not in ERRORS:
        raise SceneError(f"{where}: error={shown(error)} is unknown; allowed: one of {', '.join(ERRORS)}")
    return [CalibCell(scene, tuple(sorted(scene_params.items())), n, refine, metric, reference, error, refine_read)
            for n in ns]


def parse_calibrations(items: Any, where: str) -> list[Calibration]:
    """Check every `[[calibration]]` table of a study file; SceneError (one line) names the first bad field,
    and the overlapping cells of a calibration whose calibration and validation cells overlap."""
    if not (isinstance(items, list) and all(isinstance(t, dict) for t in items)):
        raise SceneError(f"{where}: calibration={shown(items)} is not valid; allowed: [[calibration]] tables")
    out: list[Calibration] = []
    ids: set[str] = set()
    for k, item in enumerate(items):
        at = f"{where} calibration {k + 1}"
        _unknown(item, CALIBRATION_KEYS, "a [[calibration]]", at)
        cid = item.get("id", f"calibration{k + 1}")
        safe_name(cid, "id", at)
        if cid in ids:
            raise SceneError(f"{at}: id={cid!r} is used by another calibration; allowed: one id per calibration")
        ids.add(cid)
        at = f"{where} calibration {cid!r}"
        try:
            solver = get_solver(str(item.get("solver")))
        except (SolverUnavailable, SceneError) as exc:
            raise SceneError(f"{at}: {exc}") from None
        fixed = dict(_table(item.get("solver_params", {}), "solver_params", at))
        _solver_params_ok(solver, fixed, at)
        params = item.get("parameter")
        if not isinstance(params, list) or not params:
            raise SceneError(f"{at}: no [[calibration.parameter]] tables; allowed: one or more free parameters")
        free = [_parameter(p, solver, fixed, f"{at} parameter {i + 1}") for i, p in enumerate(params)]
        if len({p.name for p in free}) != len(free):
            raise SceneError(f"{at}: a parameter is named twice; allowed: each free parameter once")
        cells = {}
        for role in ("calibrate", "validate"):
            tables = item.get(role)
            if not isinstance(tables, list) or not tables:
                raise SceneError(f"{at}: no [[calibration.{role}]] tables; allowed: one or more cells")
            cells[role] = [c for i, t in enumerate(tables)
                           for c in _cells(t, f"{at} {role} {i + 1}", uses_refine(solver))]
        _overlap(cells["calibrate"], cells["validate"], solver, at)
        opts = _options(item, at)
        budget = opts.get("budget", Calibration.budget)
        if budget < len(cells["calibrate"]):
            raise SceneError(f"{at}: budget={budget}{'' if 'budget' in item else ' (the default)'} is below the "
                             f"{len(cells['calibrate'])} calibration cells (one parameter set costs one run per cell: "
                             f"nothing would be evaluated); allowed: integer in [{len(cells['calibrate'])}, 100000]")
        replicas = _table(item.get("replicas", {}), "replicas", at)
        reps = tuple((k2, tuple(v if isinstance(v, list) else [v])) for k2, v in sorted(replicas.items()))
        for name, values in reps:
            if name in {p.name for p in free}:
                raise SceneError(f"{at}: replicas.{name} names a free parameter (the optimum would override it); "
                                 "allowed: a fixed parameter of the solver (a seed, a run length, ...)")
            for v in values:
                _solver_params_ok(solver, fixed | {name: v}, f"{at} replicas.{name}")
        defaults = effective_params(solver, fixed)
        out.append(Calibration(cid, str(item.get("title", cid)), solver.name, tuple(sorted(fixed.items())),
                               tuple(free), tuple(cells["calibrate"]), tuple(cells["validate"]), replicas=reps,
                               defaults={p.name: defaults[p.name] for p in free}, **opts))
    return out


def _overlap(calibrate: list[CalibCell], validate: list[CalibCell], solver: Any, at: str) -> None:
    """Refuse validation cells that measure a number the parameters were fitted to: the same metric of the same
    run as the solver sees it (`CalibCell.key`: what it reads of the scene, n, and refine only if it uses it;
    its parameters are the same in every cell of a calibration: the fixed ones and the fitted values)."""
    fitted = {c.measure(): c for c in calibrate}
    overlap = []
    for v in validate:
        c = fitted.get(v.measure())
        if c is not None:
            same = "" if c.describe() == v.describe() else f" (the run of calibration cell {c.describe()})"
            overlap.append(f"{v.describe()} {v.metric}{same}")
    if overlap:
        why = "" if uses_refine(solver) else f"; {solver.name} ignores refine"
        raise SceneError(f"{at}: calibration and validation cells overlap ({'; '.join(overlap)}{why}); allowed: "
                         "validation cells held out from calibration (another scene, resolution or metric: one that "
                         "changes what the solver computes)")


def _options(item: dict[str, Any], at: str) -> dict[str, Any]:
    """The search options with their ranges."""
    opts: dict[str, Any] = {}
    for key, (low, high) in {"budget": (1, 100_000), "design_points": (1, 4096), "starts": (0, 64),
                             "seed": (0, 2**31 - 1)}.items():
        if key in item:
            opts[key] = _integer(item[key], key, at, low, high)
    if "design" in item:
        if item["design"] not in DESIGNS:
            raise SceneError(f"{at}: design={shown(item['design'])} is unknown; allowed: one of {', '.join(DESIGNS)}")
        opts["design"] = item["design"]
    for key, (low, high) in {"noise_factor": (0.0, 100.0), "noise_floor": (0.0, math.inf),
                             "sensitivity_step": (1e-6, 0.5), "tolerance": (0.0, math.inf)}.items():
        if key in item:
            v = item[key]
            if not _number(v) or not low <= v <= high:
                raise SceneError(f"{at}: {key}={shown(v)} is not valid; allowed: number in [{low:g}, {high:g}]")
            opts[key] = float(v)
    return opts
