"""Stability measurements: where a solver's time stepping really becomes unstable, against its theory.

A solver refuses a time step above its theoretical limit (input validation), so measuring the limit
needs the solver's optional stability probe (`solver.stability_probe()`, kept beside the solver): it
prepares the run the solver would make and integrates it at dt = ratio * dt_theory, beyond the guard,
and states its theory.  This module holds only what is generic: the probe's own parameters, the
bisection, the map run, and the tables the report draws.  Two cell tasks use it:

- "limit": bisection on ratio = dt / dt_theory between `ratio_lo` (must be stable) and `ratio_hi` (must
  be unstable) down to `ratio_tol`; the limit is reported in the probe's quantity next to the theory,
  and optionally (`linear`) next to the probe's linear-discrete limit;
- "map": one run at `dt_ratio`, classified by the solver (ok, unstable, defect, non-stationary) and
  re-checked independently by the probe on the final state: a blow-up the solver did not report is
  counted as `undetected`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import pandas as pd

from pcverify.scene import Param, Resolution, Scene, SceneError, resolve_params
from pcverify.solvers.protocol import ProbeSetup, Solver, StabilityProbe

PROBE_KINDS = ("limit", "map")
PROBE_PARAMS: tuple[Param, ...] = (
    Param("dt_ratio", 1.0, "", "map: dt / dt_theory of the run", low=0.0, high=10.0, low_open=True),
    Param("ratio_lo", 0.05, "", "limit: lower bracket of dt / dt_theory (must be stable)", low=0.0, high=10.0,
          low_open=True),
    Param("ratio_hi", 1.5, "", "limit: upper bracket of dt / dt_theory (must be unstable)", low=0.0, high=10.0,
          low_open=True),
    Param("ratio_tol", 1e-3, "", "limit: bisection stops when the bracket is narrower than this", low=1e-6,
          high=0.5),
    Param("linear", False, "", "limit: also compute the linear-discrete limit (dense eigenvalues; n <= 5)",
          kind=bool),
)
PROBE_NAMES = {p.name for p in PROBE_PARAMS}


class ProbeUnavailable(LookupError):
    """A solver without a stability probe (the study skips its cells with this reason)."""


def probe_of(solver: Solver) -> StabilityProbe:
    """The solver's stability probe; ProbeUnavailable (a skip reason) if it offers none."""
    make = getattr(solver, "stability_probe", None)  # optional part of the solver protocol
    if make is None:
        raise ProbeUnavailable(f"solver {solver.name!r} has no stability probe (a solver offers one with "
                               "stability_probe(), which runs its kernel at a dt above its own guard)")
    return make()


def split_params(params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(solver params, probe params) of a cell; probe params validated against PROBE_PARAMS."""
    solver = {k: v for k, v in params.items() if k not in PROBE_NAMES}
    probe = resolve_params(PROBE_PARAMS, {k: v for k, v in params.items() if k in PROBE_NAMES}, "stability probe")
    for key in ("dt", "safety"):
        if key in solver:
            raise SceneError(f"{key}={solver[key]!r} is not allowed in a stability cell; allowed: set dt_ratio "
                             "(the probe sets dt = dt_ratio * dt_theory)")
    return solver, probe


def measure_limit(probe: StabilityProbe, setup: ProbeSetup, lo: float, hi: float, tol: float) -> dict[str, Any]:
    """Bisection on ratio = dt / dt_theory for the onset of status 'unstable'.

    Assumes one crossing inside [lo, hi]; the bracket ends are checked first and the verdict says so
    when lo is already unstable or hi still stable.  Every run's verdict is counted."""
    runs = []

    def unstable(r: float) -> bool:
        out = probe.run(setup, r)
        runs.append(out)
        return out.status == "unstable"

    verdict = "bisected"
    if unstable(lo):  # blows up however small dt is: the drive, not the time step, is unstable
        verdict, hi = f"unstable at every dt tried, down to ratio_lo={lo:g}: not a time-step limit", lo
    elif not unstable(hi):
        verdict, lo = f"stable up to ratio_hi={hi:g}", hi
    else:
        while hi - lo > tol:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
    ratio = 0.5 * (lo + hi)
    return {"verdict": verdict, "ratio_stable": lo, "ratio_unstable": hi, "measured_ratio": ratio,
            "measured_safety": ratio * setup.theory_limit, "runs": len(runs),
            "undetected": sum(r.undetected for r in runs),
            "unstable_runs": sum(r.status == "unstable" for r in runs)}


@dataclass(frozen=True)
class StabilityTask:
    """The cell task of a stability group: a limit bisection or one map run, through the solver's probe."""

    kind: str  # "limit" or "map"

    @property
    def name(self) -> str:
        return f"stability-{self.kind}"

    def supports(self, solver: Solver, scene: Scene) -> tuple[bool, str]:
        try:
            return probe_of(solver).supports(scene)
        except ProbeUnavailable as exc:
            return False, str(exc)

    def check(self, solver: Solver, params: dict[str, Any]) -> dict[str, Any]:
        """A cell's parameters checked before anything runs (SceneError names the bad one): the given
        solver parameters and the probe's effective ones."""
        solver_params, probe_params = split_params(params)
        resolve_params(solver.parameters, solver_params, f"solver {solver.name!r}")
        return solver_params | probe_params

    def run(self, solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> dict[str, Any]:
        """Result of one stability cell (JSON-ready): status, reason and a summary of scalars."""
        t0 = time.perf_counter()
        probe = probe_of(solver)
        solver_params, pp = split_params(params)
        setup = probe.prepare(scene, resolution, solver_params)
        ctx = setup.context
        head = {"omega_max": ctx.get("omega_max", math.nan), "zeta": ctx.get("damping_ratio", math.nan),
                "dt_theory": setup.dt_theory, "safety_theory": setup.theory_limit,
                "solver_dt_limit_ratio": setup.solver_dt_limit / setup.dt_theory,
                "drive_amplitude": ctx.get("drive_amplitude", math.nan), "probe": self.kind,
                "quantity": setup.quantity, "theory_label": setup.theory_label, "x_axis": setup.x_axis}
        if self.kind == "map":
            out = probe.run(setup, pp["dt_ratio"])
            summary = head | {"dt": out.dt, "dt_ratio": out.dt_ratio, "safety": out.dt_ratio * setup.theory_limit,
                              "steps": out.steps, "steps_planned": out.steps_planned,
                              "stopped_at_step": out.stopped_at_step, "kernel_status": out.kernel_status,
                              "hops": out.details.get("hops", 0)}
            summary |= {k: v for k, v in out.details.items() if k != "hops"}
            summary |= {"blown": out.blown, "undetected": out.undetected}
            status, reason = out.status, out.reason
        else:
            lim = measure_limit(probe, setup, pp["ratio_lo"], pp["ratio_hi"], pp["ratio_tol"])
            summary = head | lim | {"ratio_tol": pp["ratio_tol"]}
            if pp["linear"]:
                summary["linear_safety"] = probe.linear_limit(setup)
            summary["relative_deviation"] = lim["measured_safety"] / setup.theory_limit - 1.0
            status, reason = "ok", "" if lim["verdict"] == "bisected" else lim["verdict"]
        return {"status": status, "reason": reason, "summary": summary, "theory": probe.theory,
                "wall_s": time.perf_counter() - t0, "resolution": {"n": resolution.n, "refine": 1}}


def tables(results: list[dict[str, Any]], probe: str = "limit") -> tuple[pd.DataFrame, pd.DataFrame]:
    """(limits, map) tables of a stability group's cell results.  A measured row has status ok (a map row's
    `run_status` is what the run it measured did); a cell with no measurement (skipped, or the cell raised)
    is a row of its group's table (`probe`) with its status and reason, so a claim over it cannot pass."""
    rows: dict[str, list[dict[str, Any]]] = {"limit": [], "map": []}
    for r in results:
        s = r.get("summary") or {}
        sp = r.get("solver_params") or {}
        if "probe" not in s:
            row = {"solver": r["solver"], "scene": r["scene"], "n": r["n"], "status": r.get("status"),
                   "reason": r.get("reason") or "", "damping_ratio": sp.get("damping_ratio"),
                   "drive_amplitude": sp.get("drive_amplitude"), "damping": sp.get("damping")}
            rows[probe].append(row)
            continue
        row = {"solver": r["solver"], "scene": r["scene"], "n": r["n"], "status": "ok", "reason": "",
               "damping_ratio": s["zeta"], "drive_amplitude": s.get("drive_amplitude", sp.get("drive_amplitude")),
               "damping": sp.get("damping"),
               "safety_theory": s["safety_theory"]}
        if s["probe"] == "limit":
            row |= {k: s.get(k) for k in ("measured_safety", "linear_safety", "relative_deviation", "ratio_tol",
                                          "verdict", "runs", "unstable_runs", "undetected")}
        else:
            row |= {"dt_ratio": s["dt_ratio"], "safety": s["safety"], "run_status": r["status"],
                    "run_reason": r.get("reason") or "", "kernel_status": s["kernel_status"],
                    "stopped_at_step": s["stopped_at_step"], "steps_planned": s["steps_planned"], "hops": s["hops"],
                    "undetected": s["undetected"]}
        rows[s["probe"]].append(row)
    return pd.DataFrame(rows["limit"]), pd.DataFrame(rows["map"])
