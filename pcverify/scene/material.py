"""Materials: constants in SI units, and the uniaxial response function of a breakable material."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .params import SceneError, shown

RESPONSES = ("elastic", "degradation", "plastic", "plastic-degradation")


def _number(v: object) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not math.isinf(v)


@dataclass(frozen=True)
class Material:
    """Material constants in SI units; NaN where a scene does not need one (the scene checks what it needs)."""

    name: str
    density: float
    conductivity: float = math.nan
    heat_capacity: float = math.nan
    youngs_modulus: float = math.nan
    poisson_ratio: float = math.nan

    def __post_init__(self) -> None:
        if not (_number(self.density) and 0 < self.density <= 1e6):
            raise SceneError(f"density={shown(self.density)} is out of range; allowed: number in (0, 1e6] kg/m^3")
        for name, unit in (("conductivity", "W/(m K)"), ("heat_capacity", "J/(kg K)"), ("youngs_modulus", "Pa")):
            v = getattr(self, name)
            if not (_number(v) and (math.isnan(v) or 0 < v <= 1e15)):
                raise SceneError(f"{name}={shown(v)} is out of range; allowed: number in (0, 1e15] {unit}")
        nu = self.poisson_ratio
        if not (_number(nu) and (math.isnan(nu) or -1.0 < nu < 0.5)):
            raise SceneError(f"poisson_ratio={shown(nu)} is out of range; allowed: number in (-1, 0.5)")

    @property
    def diffusivity(self) -> float:
        """Thermal diffusivity k / (rho c) in m^2/s."""
        return self.conductivity / (self.density * self.heat_capacity)

    def require(self, *names: str) -> None:
        """SceneError unless every named constant is given (not NaN)."""
        missing = [n for n in names if math.isnan(getattr(self, n))]
        if missing:
            raise SceneError(f"material {self.name!r}: {missing[0]} is missing; allowed: a positive number")


ALUMINIUM = Material("aluminium", density=2700.0, conductivity=237.0, heat_capacity=897.0)
DURALUMIN = Material("duralumin", density=2800.0, youngs_modulus=70e9, poisson_ratio=0.33)
MATERIALS = {m.name: m for m in (ALUMINIUM, DURALUMIN)}


@dataclass(frozen=True)
class Response:
    """Uniaxial response function sigma = f(eps) of the material (Fig. 3 of the MCA paper; docs/physics.md,
    "The movable cellular automaton (MCA) model").

    elastic: linear to the strength sigma_c, then fracture.  degradation: linear to sigma_d, then a
    softening branch to sigma_c at eps_c; unloading with the reduced (secant) modulus.  plastic:
    linear to sigma_y, then hardening with modulus `hardening` (Pa) to sigma_c.  plastic-degradation:
    both.  k = sigma_c / sigma_t enters the Drucker-Prager equivalent stress of the fracture criterion.
    """

    kind: str = "elastic"
    sigma_c: float = 400e6
    sigma_d: float = 320e6
    sigma_y: float = 300e6
    hardening: float = 7e9
    k: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in RESPONSES:
            raise SceneError(f"response={shown(self.kind)} is not allowed; allowed: {', '.join(RESPONSES)}")
