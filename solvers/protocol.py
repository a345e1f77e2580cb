"""The solver contract: the Solver protocol, the Solution every solver returns, and the optional
stability probe.

A solver turns (scene, resolution, parameters) into a Solution: values at the scene's sample points,
the cost, and diagnostics.  Solvers know nothing about studies or reports: they import the scene model
(`pcverify.scene`) and nothing of the harness.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from pcverify.scene import Param, Resolution, Scene, resolve_params

STATUSES = ("ok", "unstable", "skipped", "non-stationary", "defect", "failed")
KINDS = ("particle", "continuum")  # a solver's `kind`: the figures draw particles as markers, continua as lines


@dataclass
class Solution:
    """What a solver returns: sample values, cost, diagnostics (JSON-ready via to_dict).

    samples: per sample-set name, {"points": (k, 3) array, "values": (k,) array}; for heat scenes the values
    are T / t_max (particle solvers: relative hotness).  unknowns (and work.unknowns): the values the solver
    solves for or advances in time that no constraint holds (free nodes, cells, dofs, particles' coordinates,
    temperatures): the one count every cost table and figure uses.  work: counters (unknowns, time_steps,
    pair_steps, iterations, kernel_s, ...).  summary: scalar results (solvers may add keys, never rename).
    """

    scene: str
    solver: str
    params: dict[str, Any]
    resolution: dict[str, Any]
    samples: dict[str, dict[str, np.ndarray]]
    unknowns: int
    wall_s: float
    status: str = "ok"
    reason: str = ""
    quantity: str = "T/t_max"
    work: dict[str, Any] = field(default_factory=dict)
    summary: dict[str, Any] = field(default_factory=dict)
    diagnostics: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.status not in STATUSES:
            raise ValueError(f"status={self.status!r}; allowed: {', '.join(STATUSES)}")

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-serialisable dict (the public `--json` interface), its keys in the order of DICT_KEYS."""
        return _jsonable({key: getattr(self, key) for key in DICT_KEYS})


DICT_KEYS = ("scene", "solver", "params", "resolution", "unknowns", "wall_s", "status", "reason", "quantity", "samples",
             "summary", "work", "diagnostics")


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (np.bool_, bool)):
        return bool(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


class Solver(Protocol):
    """The solver protocol (docs/plugins.md: what a solver declares and returns).

    name: the registry name.  kind: "particle" or "continuum".  parameters: every parameter `solve` takes, with
    its default, unit and range.  Optional: `stability_probe() -> StabilityProbe`, `estimate(scene, resolution,
    **params) -> WorkEstimate` (work beyond the limits is refused before it starts), `uses_refine` (see
    `uses_refine`) and `notes` (the model notes: see `model_notes`).  No version: the cache key holds a
    fingerprint of the code the solver reaches by import.
    """

    name: str
    kind: str
    parameters: tuple[Param, ...]

    def supports(self, scene: Scene) -> tuple[bool, str]:
        """Whether this solver can do `scene`, and if not, why."""
        ...

    def solve(
        self,
        scene: Scene,
        resolution: Resolution,
        samples: dict[str, np.ndarray] | None = None,
        **params: Any,
    ) -> Solution:
        """Solve `scene` at `resolution`; report at `samples` (default: scene.sample_sets(n))."""
        ...


@dataclass(frozen=True)
class WorkEstimate:
    """What a solve will cost, known before it starts (a solver's optional `estimate`): the unknowns, the
    time steps (1 for a steady or eigen solve) and the memory in bytes (an upper estimate)."""

    unknowns: int
    steps: int = 1
    bytes: int = 0


@dataclass(frozen=True)
class ProbeSetup:
    """A stability probe's prepared case: everything before integration, and where ratio 1 sits.

    dt_theory: the step of ratio 1 (s); a limiting ratio r is r * theory_limit in `quantity` (e.g. "dt
    omega_max / 2"); x_axis: the context key (or "n") the report plots the limit against; solver_dt_limit:
    what the solver's own input guard allows (s; nan if none); context: scalars reported beside the
    measurement; state: the model's prepared run (private to the probe).
    """

    dt_theory: float
    theory_limit: float
    quantity: str
    theory_label: str
    x_axis: str = "n"
    solver_dt_limit: float = math.nan
    context: dict[str, Any] = field(default_factory=dict)
    state: Any = None


@dataclass(frozen=True)
class ProbeRun:
    """One probe run at dt = dt_ratio * dt_theory: the solver's status, how far it got, and an independent
    re-check of the final state (`blown`; `undetected`: blown but not reported unstable by the solver).
    details: model-specific numbers (hops, stationarity, displacement, ...)."""

    status: str
    reason: str
    dt: float
    dt_ratio: float
    steps: int
    steps_planned: int
    stopped_at_step: int
    kernel_status: str
    blown: bool
    undetected: bool
    details: dict[str, Any] = field(default_factory=dict)


class StabilityProbe(Protocol):
    """Measures where a solver's time stepping becomes unstable, beyond the solver's own input guard.

    theory: the stated theory of the limit.  `prepare` validates the parameters (SceneError) and builds
    the case; `run` integrates it at dt = dt_ratio * dt_theory; `linear_limit` is the exact limit of the
    linearised scheme in the setup's quantity, nan if the probe has none.
    """

    theory: str

    def supports(self, scene: Scene) -> tuple[bool, str]:
        ...

    def prepare(self, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> ProbeSetup:
        ...

    def run(self, setup: ProbeSetup, dt_ratio: float) -> ProbeRun:
        ...

    def linear_limit(self, setup: ProbeSetup) -> float:
        ...


def uses_refine(solver: Solver) -> bool:
    """Whether `refine` changes what `solver` computes: its `uses_refine` attribute when it declares one (a
    bool), else True for the continuum kind (a grid of h = a / refine) and False for the particle kind.  Cells
    that differ only in a refine the solver ignores are the same run (the calibration's overlap guard)."""
    declared = getattr(solver, "uses_refine", None)
    return declared if isinstance(declared, bool) else solver.kind == "continuum"


def read_notes(path: Path) -> tuple[str, ...]:
    """Model notes kept in a text file beside a solver: one note per paragraph (blank lines between), lines
    starting with '#' left out.  A data file rather than code, so that editing a note changes no fingerprint
    and recomputes no cached result."""
    text = "\n".join(line for line in path.read_text(encoding="utf-8").splitlines() if not line.startswith("#"))
    return tuple(" ".join(par.split()) for par in text.split("\n\n") if par.strip())


def model_notes(solver: Solver) -> tuple[str, ...]:
    """The solver's model notes (its optional `notes`): the non-empty sentences, in order; () without any.  A
    `notes` that is not a sequence of text raises TypeError naming the solver (a plugin's mistake shown, not
    dropped)."""
    notes = getattr(solver, "notes", ())
    if isinstance(notes, str) or not isinstance(notes, (tuple, list)) or not all(isinstance(t, str) for t in notes):
        raise TypeError(f"solver {getattr(solver, 'name', solver)!r}: notes={notes!r} is not valid; allowed: a tuple "
                        "of sentences (str)")
    return tuple(t.strip() for t in notes if t.strip())


def effective_params(solver: Solver, given: dict[str, Any]) -> dict[str, Any]:
    """All effective parameter values of `solver`; unknown or out-of-range values raise SceneError."""
    return resolve_params(solver.parameters, given, f"solver {solver.name!r}")


def skipped(scene: Scene, solver: Solver, resolution: Resolution, reason: str) -> Solution:
    """A Solution that records a skip and its reason (never a pass, never silent)."""
    return Solution(
        scene=scene.name, solver=solver.name, params={}, resolution={"n": resolution.n, "refine": resolution.refine},
        samples={}, unknowns=0, wall_s=0.0, status="skipped", reason=reason, quantity=scene.quantity,
    )


def heat_summary(values_at_nodes: np.ndarray, volume_mean: float) -> dict[str, float]:
    """Summary scalars every heat solver reports: bulk median over nodes and the volume mean."""
    return {"bulk_median": float(np.median(values_at_nodes)), "volume_mean": float(volume_mean)}
