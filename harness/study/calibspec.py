"""Calibration as study data: the `[[calibration]]` tables of a study file, read and checked.

A calibration names a solver, its fixed parameters, the free parameters with bounds (`log = true` to
search in log space), the calibration cells (scene, n, metric, reference) the objective is measured on,
and the validation cells held out from it.  A calibration whose calibration and validation cells
overlap (the same metric of the same run as the solver sees it: what it reads of the scene, the resolution,
and refine only for a solver that uses it) is refused with the cells named: a number the parameters were
fitted to is not a validation.  Another metric of a calibration cell's run
(torsion beside the bending frequency it was fitted to) is allowed, and the validation table says that
it shares the run.  `pcverify.harness.run.calibration`
runs what this module describes; everything here is checked before any cell runs, with one-line
SceneErrors like the other study-file errors: also a budget below the number of calibration cells (it
would evaluate nothing) and replicas that name a free parameter (the optimum would override them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.schema import (
    CALIBRATION,
    CALIBRATION_CELL,
    PARAMETER,
    STUDY,
    as_list,
    check_value,
    row_where,
)
from pcverify.scene import Scene, SceneError, shown
from pcverify.solvers.protocol import effective_params, uses_refine
from pcverify.solvers.registry import SolverUnavailable, get_solver

FIELD_KINDS = (".l2", ".linf")  # metrics <sample set>.l2 / .linf are field errors against the analytic solution
OPTIONS = ("budget", "design", "design_points", "starts", "seed", "noise_factor", "noise_floor", "sensitivity_step",
           "tolerance")  # the search options, with their defaults on `Calibration` and ranges in `schema.CALIBRATION`


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
    budget: int = CALIBRATION.field("budget").default  # the search options' defaults are the schema's
    design: str = CALIBRATION.field("design").default
    design_points: int = CALIBRATION.field("design_points").default
    starts: int = CALIBRATION.field("starts").default
    seed: int = CALIBRATION.field("seed").default
    replicas: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    noise_factor: float = CALIBRATION.field("noise_factor").default
    noise_floor: float = CALIBRATION.field("noise_floor").default
    sensitivity_step: float = CALIBRATION.field("sensitivity_step").default
    tolerance: float = math.nan
    defaults: dict[str, Any] = field(default_factory=dict)  # the solver's declared values of the free parameters


def _solver_params_ok(solver: Any, params: dict[str, Any], where: str) -> dict[str, Any]:
    try:
        return effective_params(solver, params)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None


def _parameter(item: dict[str, Any], solver: Any, fixed: dict[str, Any], where: str) -> FreeParam:
    name, low, high, log = item["name"], item["low"], item["high"], item["log"]
    known = [p.name for p in solver.parameters]
    if name not in known:
        raise SceneError(f"{where}: name={shown(name)} is not a parameter of solver {solver.name!r}; allowed: one "
                         f"of {', '.join(known)}")
    if name in fixed:
        raise SceneError(f"{where}: {name} is both free and fixed (solver_params); allowed: one of the two")
    if not low < high:
        raise SceneError(f"{where}: low={shown(low)}, high={shown(high)} are not valid; allowed: numbers with "
                         "low < high")
    if log and low <= 0:
        raise SceneError(f"{where}: low={shown(low)} is not valid with log = true; allowed: low > 0")
    for bound in (low, high):  # both bounds inside the solver's declared range
        _solver_params_ok(solver, fixed | {name: float(bound)}, f"{where} ({name} bound)")
    return FreeParam(name, float(low), float(high), log)


def _reference(value: Any, where: str) -> Reference | None:
    if value == "analytic":
        return None
    refine = value["refine"]
    refines = as_list(refine)
    if len(refines) == 2 or len(set(refines)) != len(refines):
        raise SceneError(f"{where}: reference.refine={shown(refine)} is not valid; allowed: one integer, or a list "
                         "of three or more different integers (Richardson)")
    params = value.get("solver_params", {})
    return Reference(value["solver"], value.get("n"), tuple(refines), tuple(sorted(params.items())))


def _cells(item: dict[str, Any], where: str, refine_read: bool) -> list[CalibCell]:
    scene_params = item.get("scene_params", {})
    try:
        scene = make_scene(item["scene"], **scene_params)
    except SceneError as exc:
        raise SceneError(f"{where}: {exc}") from None
    metric, reference = item["metric"], _reference(item["reference"], where)
    if metric.endswith(FIELD_KINDS) and reference is not None:
        raise SceneError(f"{where}: metric={metric!r} is a field error against the analytic solution; allowed: "
                         "reference = \"analytic\" with it")
    if reference is None and not metric.endswith(FIELD_KINDS):
        raise SceneError(f"{where}: metric={metric!r} with reference = \"analytic\"; allowed: a field error "
                         "<samples>.l2 or .linf (a scalar metric needs a solver reference)")
    return [CalibCell(scene, tuple(sorted(scene_params.items())), n, item["refine"], metric, reference,
                      item["error"], refine_read) for n in as_list(item["n"])]


def parse_calibrations(items: Any, where: str) -> list[Calibration]:
    """Check every `[[calibration]]` table of a study file against `schema.CALIBRATION`, then against its solver
    and scenes; SceneError (one line) names the first bad field, and the overlapping cells of a calibration
    whose calibration and validation cells overlap."""
    out: list[Calibration] = []
    for number, (given, item) in enumerate(zip(items, check_value(items, STUDY.field("calibration"), where),
                                               strict=True), 1):
        at = row_where(where, "calibration", number, item, CALIBRATION)
        cid = item.get("id", CALIBRATION.default_key.format(number))
        try:
            solver = get_solver(item["solver"])
        except (SolverUnavailable, SceneError) as exc:
            raise SceneError(f"{at}: {exc}") from None
        fixed = dict(item.get("solver_params", {}))
        _solver_params_ok(solver, fixed, at)
        free = [_parameter(p, solver, fixed, row_where(at, "parameter", i, p, PARAMETER))
                for i, p in enumerate(item["parameter"], 1)]
        cells = {role: [c for i, t in enumerate(item[role], 1)
                        for c in _cells(t, row_where(at, role, i, t, CALIBRATION_CELL), uses_refine(solver))]
                 for role in ("calibrate", "validate")}
        _overlap(cells["calibrate"], cells["validate"], solver, at)
        opts = {k: float(item[k]) if isinstance(getattr(Calibration, k), float) else item[k] for k in OPTIONS
                if k in item}
        budget = opts["budget"]
        if budget < len(cells["calibrate"]):
            raise SceneError(f"{at}: budget={budget}{'' if 'budget' in given else ' (the default)'} is below the "
                             f"{len(cells['calibrate'])} calibration cells (one parameter set costs one run per cell: "
                             f"nothing would be evaluated); allowed: integer in [{len(cells['calibrate'])}, 100000]")
        reps = tuple((k, tuple(as_list(v))) for k, v in sorted(item.get("replicas", {}).items()))
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
