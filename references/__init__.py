"""Analytic solutions and figures taken from the papers (with their source).

`analytic(scene, points)` returns the exact T / t_max at the points where the scene
has an analytic solution, and None where it has none (the harness then uses a
continuum reference).
"""

from __future__ import annotations

import numpy as np

from pcverify.references.slab import Slab
from pcverify.scene import FaceTemperature, Scene, TemperatureConstraint


def slab_of(scene: Scene) -> tuple[Slab, int] | None:
    """The one-dimensional problem a heat scene reduces to, and its axis, or None.

    It does when every temperature constraint is a FaceTemperature and they hold the two faces of one axis
    (or there is none: an insulated body), and an interface flux, if any, lies across that axis; the initial
    temperature and the volumetric source are uniform in every scene.  Not one with dissimilar blocks (a contact
    whose body 1 has thermal constants of its own): the slab is one material.
    """
    heat = scene.conduction
    if heat is None:
        return None
    contact = scene.contact
    if contact is not None and (contact.base_conductivity is not None or contact.base_heat_capacity is not None):
        return None
    plane = heat.interface if heat.interface is not None and heat.interface.flux != 0.0 else None
    faces = {c.face: c.value for c in scene.constraints if isinstance(c, FaceTemperature)}
    thermal = [c for c in scene.constraints if isinstance(c, TemperatureConstraint)]
    if len(faces) != len(thermal):  # mechanical supports do not touch the heat problem
        return None
    if faces:
        axes = {face[0] for face in faces}
        if len(faces) != 2 or len(axes) != 1:
            return None
        axis = "xyz".index(axes.pop())
        held: tuple[float, float] | None = (faces["xyz"[axis] + "0"], faces["xyz"[axis] + "WHL"[axis]])
    else:
        axis, held = plane.axis_index if plane is not None else 2, None
    if plane is not None and plane.axis_index != axis:
        return None
    mat = scene.material
    return Slab(float(scene.box.extent[axis]), mat.conductivity, mat.diffusivity, held=held,
                initial=heat.initial_temperature, source=heat.source,
                flux=plane.flux if plane is not None else 0.0,
                plane=plane.position if plane is not None else 0.0), axis


def analytic(scene: Scene, points: np.ndarray) -> np.ndarray | None:
    """Exact relative temperature at `points`, or None if the scene has no analytic solution."""
    found = slab_of(scene)
    if found is None:
        return None
    slab, axis = found
    heat = scene.conduction
    coord = np.asarray(points, dtype=float).reshape(-1, 3)[:, axis]
    if heat.mode == "steady":
        if slab.held is None:
            return None
        return slab.steady(coord) / heat.t_max
    return slab.transient(coord, heat.t_end, tol=1e-12 * heat.t_max) / heat.t_max
