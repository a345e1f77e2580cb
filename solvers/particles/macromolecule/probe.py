"""Stability probe of the macromolecule solver: the solver's own solve, at a step chosen by the probe.

Theory (THEORY): the Jury criterion of the scheme with lagged damping for the top mode.  The linear-discrete
limit is where the spectral radius of the linearised, held lattice's one-step map crosses 1.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.scene import Resolution, Scene
from pcverify.solvers.protocol import ProbeRun, ProbeSetup, Solver, effective_params

from .modal import damping_matrix, free_dofs, hessian, linear_step_limit
from .setup import prepare

THEORY = ("velocity Verlet with radial pair damping lagged half a step: a mode of frequency omega and damping ratio "
          "zeta is stable for omega dt / 2 < sqrt(1 + zeta^2) - zeta (Jury criterion of x_{n+1} - 2x_n + x_{n-1} = "
          "-h^2 x_n - 2 zeta h (x_n - x_{n-1}), h = omega dt); the top mode (omega_max, zeta from the damped modal "
          "problem) sets dt_theory")

_LINEAR_LIMITS: dict[tuple, float] = {}  # by lattice and damping: one dense eigenvalue bisection per process


class MacromoleculeProbe:
    """Solves with the macromolecule solver at dt = ratio * dt_theory, beyond its input guard (dt_guard false)."""

    theory = THEORY

    def __init__(self, solver: Solver) -> None:
        self.solver = solver

    def supports(self, scene: Scene) -> tuple[bool, str]:
        return self.solver.supports(scene)

    def prepare(self, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> ProbeSetup:
        """Everything before a run (lattice, fixes, A, delta, zeta); dt_theory from the stated theory."""
        p = effective_params(self.solver, params)
        s = prepare(scene, resolution.n, p)
        w = 2 * math.pi * s.f_top
        limit = math.sqrt(1 + s.damping_ratio**2) - s.damping_ratio
        context = {"omega_max": w, "damping_ratio": s.damping_ratio, "drive_amplitude": p["drive_amplitude"],
                   "scene_hash": scene.content_hash(), "n": resolution.n}
        return ProbeSetup(dt_theory=2 * limit / w, theory_limit=limit, quantity="dt omega_max / 2",
                          theory_label="theory sqrt(1+zeta^2) - zeta", x_axis="damping_ratio",
                          solver_dt_limit=s.dt_limit, context=context,
                          state=(p, s, scene, resolution, dict(params)))

    def run(self, setup: ProbeSetup, dt_ratio: float) -> ProbeRun:
        """One run at dt = dt_ratio * dt_theory over the solver's window; status and an independent check of
        the final state with three criteria (finite; no particle more than a outside the bar; kinetic
        energy at most blowup_factor times the energy supplied)."""
        p, s, scene, resolution, given = setup.state
        lat, fx = s.lattice, s.fixes
        dt = dt_ratio * setup.dt_theory
        sol = self.solver.solve(scene, resolution, **(given | {"dt": dt, "dt_guard": False, "stop_tol": 0.0}))
        w = 2 * math.pi * p["drive_frequency"]
        e, x = sol.diagnostics["energy"], sol.diagnostics["positions_end"]
        finite = bool(np.isfinite(x).all() and np.isfinite(list(e.values())).all())
        disp = float(np.max(np.linalg.norm(x - lat.positions, axis=1)) / lat.a) if finite else math.inf
        outside = float(np.max(np.maximum(lat.positions.min(axis=0) - x, x - lat.positions.max(axis=0)))
                        / lat.a) if finite else math.inf
        supplied = max(e["start"] + e["drive_work"] + e["bath_work"], 0.0) + fx.energy_scale(lat.mass, w)
        ke_ratio = float(e["kinetic_end"] / supplied) if finite else math.inf
        blown = (not finite) or outside > 1.0 or ke_ratio > p["blowup_factor"]
        m = sol.summary
        return ProbeRun(status=sol.status, reason=sol.reason, dt=dt, dt_ratio=dt_ratio, steps=m["steps"],
                        steps_planned=int(round(p["t_end"] / dt)), stopped_at_step=m["stopped_at_step"],
                        kernel_status=m["kernel_status"], blown=blown,
                        undetected=bool(blown and sol.status != "unstable"),
                        details={"hops": m["hops"], "stationarity": m["stationarity"], "max_displacement_over_a": disp,
                                 "outside_over_a": outside, "kinetic_end_over_supplied": ke_ratio})

    def linear_limit(self, setup: ProbeSetup, tol: float = 1e-5) -> float:
        """dt omega_max / 2 at which the spectral radius of the linearised scheme (held lattice at rest,
        lagged pair damping; Langevin bath friction left out) crosses 1.  Independent of the drive
        amplitude and the run length, so it is memoised per lattice and damping."""
        p, s = setup.state[:2]
        w = setup.context["omega_max"]
        key = (setup.context["scene_hash"], setup.context["n"], w, s.delta,
               tuple(p[k] for k in ("p", "s", "unstable_fraction", "pairs_at_2a")), tol)
        if key not in _LINEAR_LIMITS:
            lat, dofs = s.lattice, free_dofs(~s.fixes.held)
            K = hessian(lat.positions, lat.pairs, s.model, lat.a)[dofs][:, dofs].toarray() / lat.mass
            C = damping_matrix(lat.positions, lat.pairs, s.delta)[dofs][:, dofs].toarray() / lat.mass
            _LINEAR_LIMITS[key] = linear_step_limit(K, C, w, 0.05, 1.5, tol)
        return _LINEAR_LIMITS[key]
