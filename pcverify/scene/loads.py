"""Heat released inside the body: the interface heat flux on an internal plane, and the terms of a
spatially varying volumetric source.

(The uniform volumetric source is a number, `Conduction.source`; a planar source needs a place, and a
varying one a shape, so each is a small value of its own.)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .params import SceneError, is_real, shown

AXES = ("x", "y", "z")


@dataclass(frozen=True)
class InterfaceFlux:
    """A planar heat source: the plane {axis = position} inside the body releases `flux` W/m^2.

    Split rule: the plane lies inside one continuous body, so the temperature is continuous across it
    (perfect thermal contact) and the flux is not divided by decree: conduction divides it between the
    two sides.  While both sides act as semi-infinite solids (sqrt(alpha t) small against the distance
    to the nearest other boundary) the side with effusivity e_i = sqrt(k_i rho_i c_i) takes the share
    e_i / (e_1 + e_2) of q; a body of one material gives each side q / 2, and each side of the plane
    rises as dT = 2 (q / 2) sqrt(alpha t / pi) / k.  Every solver that implements the plane follows
    this rule (scikit-fem and FiPy heat: a surface load on the plane, no condition on the split).
    """

    flux: float
    position: float
    axis: str = "z"

    def __post_init__(self) -> None:
        for name, unit in (("flux", "W/m^2"), ("position", "m")):
            v = getattr(self, name)
            ok = is_real(v) and abs(v) <= 1e15
            if not ok:
                raise SceneError(f"interface {name}={shown(v)} is out of range; allowed: number in [-1e15, 1e15] "
                                 f"{unit}")
        if self.axis not in AXES:
            raise SceneError(f"interface axis={shown(self.axis)} is not allowed; allowed: {', '.join(AXES)}")

    @property
    def axis_index(self) -> int:
        return AXES.index(self.axis)


@dataclass(frozen=True)
class SineSource:
    """One term of a volumetric heat source field: amplitude * prod_a sin(k_a x_a + phase_a) W/m^3 (x_a in m
    from the box's origin).  A cosine is a phase of pi/2, a uniform factor along an axis k_a = 0 and phase pi/2;
    a small sum of such terms (`Conduction.source_field`) is the source of a smooth 3-D manufactured solution."""

    amplitude: float
    wavenumbers: tuple[float, float, float] = (0.0, 0.0, 0.0)
    phases: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        if not (is_real(self.amplitude) and abs(self.amplitude) <= 1e15):
            raise SceneError(f"source_field amplitude={shown(self.amplitude)} is out of range; allowed: number in "
                             "[-1e15, 1e15] W/m^3")
        for name, low, high, unit in (("wavenumbers", 0.0, 1e6, "rad/m"), ("phases", -2 * math.pi, 2 * math.pi, "rad")):
            v = getattr(self, name)
            if not (isinstance(v, tuple) and len(v) == 3 and all(is_real(x) and low <= x <= high for x in v)):
                raise SceneError(f"source_field {name}={shown(v)} is out of range; allowed: a tuple of 3 numbers "
                                 f"in [{low:g}, {high:g}] {unit} (x, y, z)")

    def at(self, points: np.ndarray) -> np.ndarray:
        """The term's value (W/m^3) at points of shape (k, 3)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        return self.amplitude * np.prod(np.sin(pts * np.asarray(self.wavenumbers) + np.asarray(self.phases)), axis=1)
