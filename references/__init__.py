"""Analytic solutions and figures taken from the papers (with their source).

`analytic(scene, points)` returns the exact T / t_max at the points where the scene
has an analytic solution, and None where it has none (the harness then uses a
continuum reference).
"""

from __future__ import annotations

import numpy as np

from pcverify.references import heat_faces
from pcverify.scene import FaceTemperature, Scene


def analytic(scene: Scene, points: np.ndarray) -> np.ndarray | None:
    """Exact relative temperature at `points`, or None if the scene has no analytic solution."""
    heat = scene.conduction
    faces = {c.face: c.value for c in scene.constraints if isinstance(c, FaceTemperature)}
    if heat is None or heat.source != 0.0 or len(scene.constraints) != 2 or faces.get("z0") != heat.t_max \
            or faces.get("zL") != 0.0:
        return None
    z = np.asarray(points, dtype=float)[:, 2]
    length = scene.box.length
    if heat.mode == "steady":
        return heat_faces.steady(z, length, 1.0)
    if heat.initial_temperature != 0.0:
        return None
    return heat_faces.transient(z, heat.t_end, length, scene.material.diffusivity, 1.0)
