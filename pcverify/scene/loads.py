"""Heat released inside the body: the interface heat flux on an internal plane.

(The uniform volumetric source is a number, `Conduction.source`; a planar source needs a place, so it
is a small value of its own.)
"""

from __future__ import annotations

from dataclasses import dataclass

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
