"""Stability probe of the MCA solver: explicit heat (forward Euler) and explicit mechanics (velocity Verlet).

Mechanics: dt = cfl * 2 / omega_G with omega_G >= omega_max a Gershgorin bound, so every cfl <= 1 is stable and
the undamped limit lies at cfl = omega_G / omega_max >= 1 (damping lowers it); ratio 1 is cfl = 1.  Heat:
forward Euler is stable iff dt <= 2 / lambda_max(C^-1 L); ratio 1 is the Gershgorin step min C_i / sum_j G_ij.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import scipy.linalg as sla

from pcverify.scene import Resolution, Scene, SceneError
from pcverify.solvers.protocol import ProbeRun, ProbeSetup, Solver, effective_params

from . import heat as mca_heat
from .automata import bar_automata
from .kernels import KERNELS

HEAT_STEPS = 20_000  # a mode amplified by 1 + 1e-3 per step grows e^20 times: bisection to 1e-3 resolves it
THEORY = ("velocity Verlet: undamped, stable for omega_max dt < 2; MCA sets dt = cfl * 2 / omega_G with omega_G >= "
          "omega_max a Gershgorin bound, so every cfl <= 1 is stable (the guarantee) and the undamped limit lies at "
          "cfl = omega_G / omega_max >= 1; viscous damping lowers it (single mode: sqrt(1+zeta^2) - zeta).  Probed "
          "through the public `cfl` parameter; dt_theory = dt at cfl = 1.  Heat (transient): forward Euler, stable "
          "iff dt <= 2 / lambda_max(C^-1 L); dt_theory = the Gershgorin step min C_i / sum_j G_ij, which guarantees "
          "it (ratio 1); the exact limit is reported as the linear-discrete limit")


class McaProbe:
    """Runs the MCA solver's explicit schemes at a step chosen by the probe (heat: forward Euler at
    ratio * dt_Gershgorin; mechanics: the solver itself at cfl = ratio); which one, from the scene's analysis in
    the solver's table (`Mca.analysis`)."""

    theory = THEORY

    def __init__(self, solver: Solver) -> None:
        self.solver = solver

    def supports(self, scene: Scene) -> tuple[bool, str]:
        """The scene's analysis (the solver's table) has an explicit scheme to probe."""
        ok, why = self.solver.supports(scene)
        if not ok:
            return ok, why
        analysis = self.solver.analysis(scene)
        return (True, "") if analysis.stepping else (False, analysis.no_stepping)

    def prepare(self, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> ProbeSetup:
        if "cfl" in params or "heat_cfl" in params:
            raise SceneError("cfl and heat_cfl are not allowed in a stability cell; allowed: set dt_ratio (the probe "
                             "sets the step)")
        effective_params(self.solver, params)
        context = {"omega_max": math.nan, "damping_ratio": math.nan, "drive_amplitude": math.nan}
        if self.solver.analysis(scene).stepping == "mechanics":
            return ProbeSetup(dt_theory=math.nan, theory_limit=1.0, quantity="cfl = dt / (2 / omega_G)",
                              theory_label="Gershgorin guarantee: stable up to at least 1", context=context,
                              state=("mechanics", scene, resolution, params))
        aut = bar_automata(scene.box, resolution.n, scene.material.density)
        held, values = mca_heat.held_temperatures(scene, aut)
        mat = scene.material
        cap, g, dt_g = mca_heat.explicit_system(aut, mat.conductivity, mat.density * mat.heat_capacity, held)
        return ProbeSetup(dt_theory=dt_g, theory_limit=1.0, quantity="dt / dt_Gershgorin",
                          theory_label="Gershgorin guarantee 1 (exact: 2 / lambda_max)", solver_dt_limit=dt_g,
                          context=context | {"damping_ratio": 0.0},
                          state=("heat", aut, held, values, cap, g, scene.conduction.t_max))

    def run(self, setup: ProbeSetup, dt_ratio: float) -> ProbeRun:
        if setup.state[0] == "heat":
            return self._run_heat(setup, dt_ratio)
        _, scene, resolution, params = setup.state
        sol = self.solver.solve(scene, resolution, cfl=min(dt_ratio, 10.0), **params)  # cfl is capped at 10
        finite = all(np.all(np.isfinite(np.asarray(v["values"], dtype=float))) for v in sol.samples.values())
        steps = int(sol.summary.get("steps", sol.work.get("time_steps", 0)) or 0)
        blown = not finite and sol.status != "unstable"
        return ProbeRun(status=sol.status, reason=sol.reason, dt=float(sol.summary.get("dt", math.nan)),
                        dt_ratio=dt_ratio, steps=steps, steps_planned=steps,
                        stopped_at_step=steps if sol.status == "unstable" else -1,
                        kernel_status=sol.reason or "completed", blown=blown or sol.status == "unstable",
                        undetected=blown)

    def _run_heat(self, setup: ProbeSetup, dt_ratio: float) -> ProbeRun:
        """HEAT_STEPS forward-Euler steps at dt = ratio * dt_G; unstable when the temperature leaves
        [-1, 2] t_max (the exact field stays in [0, 1] t_max) or is not finite."""
        _, aut, held, values, cap, g, t_max = setup.state
        dt = dt_ratio * setup.dt_theory
        # a seeded 1e-9 t_max perturbation of the free automata excites every mode: symmetric data alone
        # never reach the antisymmetric top mode, and the measured limit would be that of the symmetric modes
        noise = np.random.default_rng(0).standard_normal(aut.size) * 1e-9 * t_max * (held == 0)
        st = mca_heat.heat_state(aut, values.astype(float) + noise, cap, g, held)
        KERNELS["heat"](st, mca_heat.HeatParams(dt), HEAT_STEPS)
        rel = st.temp / t_max
        blown = not bool(np.all(np.isfinite(rel))) or float(np.max(np.abs(rel - 0.5))) > 1.5
        status, reason = ("unstable", "temperature left [-1, 2] t_max (or not finite)") if blown else ("ok", "")
        return ProbeRun(status=status, reason=reason, dt=dt, dt_ratio=dt_ratio, steps=HEAT_STEPS,
                        steps_planned=HEAT_STEPS, stopped_at_step=HEAT_STEPS if blown else -1,
                        kernel_status=reason or "completed", blown=blown, undetected=False)

    def linear_limit(self, setup: ProbeSetup) -> float:
        """Heat: the exact forward-Euler limit 2 / lambda_max(C^-1 L) over the free automata, in units of
        dt_G.  Mechanics: nan (no linear-discrete limit computed)."""
        if setup.state[0] != "heat":
            return math.nan
        _, aut, held, _, cap, g, _ = setup.state
        free = np.flatnonzero(held == 0)
        lap = mca_heat.laplacian(aut, g)[free][:, free].toarray()
        lam = sla.eigh(lap, np.diag(cap[free]), eigvals_only=True)[-1]
        return float(2.0 / lam / setup.dt_theory)
