"""Explicit finite differences for transient heat conduction with a uniform source on the lattice grid of a box.

Nodes are the lattice of resolution n refined `refine` times (h = a / refine, the same grid pcverify's
continuum solvers use).  Interior: the 7-point Laplacian; insulated faces: mirror ghost nodes
(dT/dn = 0, second order); held faces keep their temperature from t = 0+.  Forward Euler with
dt = cfl * h^2 / (6 alpha) (the stability limit of the 3-D scheme is cfl = 1), rounded so that whole
steps reach t_end; because dt scales with h^2, the time error is O(h^2) like the space error, so the
scheme converges at second order in h.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
from scipy.interpolate import RegularGridInterpolator

import pcverify
from pcverify import FaceTemperature, Param, Resolution, Scene, SceneError, Solution, effective_params

AXIS = {"x": 0, "y": 1, "z": 2}


class FiniteDifferenceHeat:
    """Explicit finite differences (forward Euler, 7-point Laplacian) for transient heat with held faces."""

    name = "fd-heat"
    kind = "continuum"
    parameters = (
        Param("cfl", 0.5, "", "dt as a fraction of the stability limit h^2 / (6 alpha)", low=0.0, high=1.0,
              low_open=True),
        Param("max_steps", 10_000_000, "", "largest number of time steps", low=1, high=1e9, kind=int),
    )

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if not scene.physics <= {"conduction", "heat-source"}:
            return False, f"fd-heat does conduction with a uniform source; the scene needs {sorted(scene.physics)}"
        if scene.conduction.mode != "transient":
            return False, "fd-heat is an explicit time stepper: transient scenes only"
        if not all(isinstance(c, FaceTemperature) for c in scene.constraints):
            return False, "fd-heat holds whole faces only (no point or patch constraints)"
        return True, ""

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        t0 = time.perf_counter()
        p = effective_params(self, params)
        ok, why = self.supports(scene)
        if not ok:
            raise SceneError(why)
        heat = scene.conduction
        shape = tuple((s - 1) * resolution.refine + 1 for s in scene.box.lattice_shape(resolution.n))
        h = resolution.spacing(scene.box.width)
        alpha = scene.material.diffusivity
        steps = math.ceil(heat.t_end / (p["cfl"] * h * h / (6.0 * alpha)))
        if steps > p["max_steps"]:
            raise SceneError(f"t_end / dt = {steps} steps is out of range; allowed: at most "
                             f"max_steps={p['max_steps']}; raise cfl or max_steps")
        dt = heat.t_end / steps
        temp = np.full(shape, float(heat.initial_temperature))
        held = np.zeros(shape, dtype=bool)
        for c in scene.constraints:
            index = [slice(None)] * 3
            index[AXIS[c.face[0]]] = 0 if c.face[1] == "0" else -1
            temp[tuple(index)] = c.value
            held[tuple(index)] = True
        rate = alpha * dt / (h * h)
        rise = heat.source * dt / (scene.material.density * scene.material.heat_capacity)  # K per step
        for _ in range(steps):
            ghost = np.pad(temp, 1, mode="reflect")  # mirror nodes: zero normal gradient on free faces
            lap = (ghost[2:, 1:-1, 1:-1] + ghost[:-2, 1:-1, 1:-1] + ghost[1:-1, 2:, 1:-1] + ghost[1:-1, :-2, 1:-1]
                   + ghost[1:-1, 1:-1, 2:] + ghost[1:-1, 1:-1, :-2] - 6.0 * temp)
            temp = np.where(held, temp, temp + rate * lap)
            temp[~held] += rise
        axes = [np.linspace(0.0, e, s) for e, s in zip(scene.box.extent, shape, strict=True)]
        field = RegularGridInterpolator(axes, temp / heat.t_max)
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {k: {"points": np.asarray(v, float), "values": field(np.asarray(v, float))} for k, v in sets.items()}
        weights = np.ones(shape)
        for axis in range(3):
            edge = [slice(None)] * 3
            for end in (0, -1):
                edge[axis] = end
                weights[tuple(edge)] *= 0.5  # trapezoid rule: half weight on every face
        nodes = out["nodes"]["values"] if "nodes" in out else field(scene.sample_sets(resolution.n)["nodes"])
        summary = {"bulk_median": float(np.median(nodes)), "volume_mean": float((weights * temp).sum()
                   / weights.sum() / heat.t_max), "dt": dt, "steps": steps}
        return Solution(scene=scene.name, solver=self.name, params=p,
                        resolution={"n": resolution.n, "refine": resolution.refine, "h": h},
                        samples=out, unknowns=int((~held).sum()), wall_s=time.perf_counter() - t0, quantity="T/t_max",
                        work={"unknowns": int((~held).sum()), "time_steps": steps}, summary=summary,
                        diagnostics={"pcverify_api": pcverify.API_VERSION})
