"""A synthetic solver with a known optimum for the calibration tests (imported as a study plugin).

"calib-quadratic" reports, on any steady heat scene, the scalar q = (x - X0)^2 + 2 (log10 y - log10 Y0)^2
plus noise (in its summary, and as the value at every sample point: a solution has the scene's sample sets):
a seeded normal of standard deviation `noise` (the seed parameter picks the replica), so the objective
|q - 0| has its minimum at (X0, Y0) and a noise that replicas measure.  `fail_above`: sets with x above it
return status "defect" (a failure, never data).  Each finished solve appends one line to the file in
$CALIB_SYNTHETIC_LOG (if set), so a test counts solver runs independently of the cache's own counts.
"""

from __future__ import annotations

import math
import os
import time
from typing import Any

import numpy as np

from pcverify import Param, Resolution, Scene, Solution

X0, Y0 = 0.3, 0.01


class Quadratic:
    """Solver "calib-quadratic": a known optimum at x = 0.3, y = 0.01, with seeded noise."""

    name = "calib-quadratic"
    kind = "particle"
    parameters = (
        Param("x", 0.5, "", "first parameter", low=-1.0, high=1.0),
        Param("y", 0.1, "", "second parameter (log-scaled in the tests)", low=1e-6, high=10.0),
        Param("noise", 0.0, "", "standard deviation of the added noise", low=0.0, high=1.0),
        Param("seed", 0, "", "replica seed of the noise", low=0, high=1000, kind=int),
        Param("fail_above", 10.0, "", "x above this: status defect", low=-10.0, high=10.0),
        Param("sleep", 0.0, "s", "wall time a solve takes (the kill-and-rerun test)", low=0.0, high=10.0),
    )

    def supports(self, scene: Scene) -> tuple[bool, str]:
        return True, ""

    def solve(self, scene: Scene, resolution: Resolution, samples: Any = None, **params: Any) -> Solution:
        t0 = time.perf_counter()
        p = {q.name: q.default for q in self.parameters} | params
        time.sleep(p["sleep"])
        log = os.environ.get("CALIB_SYNTHETIC_LOG")
        if log:  # after the work: a solve killed before this line is not counted as run
            with open(log, "a") as fh:
                fh.write(f"{scene.name} n={resolution.n} {sorted(params.items())}\n")
        rng = np.random.default_rng([int(p["seed"]), resolution.n])
        q = (p["x"] - X0) ** 2 + 2 * (math.log10(p["y"]) - math.log10(Y0)) ** 2 + p["noise"] * rng.standard_normal()
        status = "defect" if p["x"] > p["fail_above"] else "ok"
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        field = {k: {"points": v, "values": np.full(len(v), q)} for k, v in sets.items()}  # q everywhere
        return Solution(scene=scene.name, solver=self.name, params=dict(p), resolution={"n": resolution.n},
                        samples=field, unknowns=1, wall_s=time.perf_counter() - t0, status=status,
                        summary={"q": float(q), "q_ref": 0.0}, work={"unknowns": 1})
