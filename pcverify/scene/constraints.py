"""What a scene holds: prescribed temperatures (at points, on patches, on faces) and mechanical supports.

Faces are named x0, xW, y0, yH, z0, zL (the box's six faces, docs/physics.md, "Conventions").
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .params import SceneError, is_real, shown

Vec3 = tuple[float, float, float]
FACES = ("x0", "xW", "y0", "yH", "z0", "zL")


def _face(face: str) -> None:
    if face not in FACES:
        raise SceneError(f"face={shown(face)} is not allowed; allowed: {', '.join(FACES)}")


@dataclass(frozen=True)
class PointTemperature:
    """Temperature prescribed at a point (the paper's corner constraint; ill-posed in 3-D)."""

    point: Vec3
    value: float


@dataclass(frozen=True)
class PatchTemperature:
    """Temperature prescribed on the solid inside a sphere of `radius` about `centre` (a corner)."""

    centre: Vec3
    radius: float
    value: float

    def __post_init__(self) -> None:
        if not (is_real(self.radius) and self.radius > 0):
            raise SceneError(f"rho={shown(self.radius)} is out of range; allowed: number in (0, inf) m")


@dataclass(frozen=True)
class FaceTemperature:
    """Temperature prescribed on a whole face."""

    face: str
    value: float

    def __post_init__(self) -> None:
        _face(self.face)


@dataclass(frozen=True)
class FaceSupport:
    """Frictionless support: the face's normal displacement is held at `displacement` (m, along the
    outward axis direction of +x/+y/+z), its tangential motion is free."""

    face: str
    displacement: float = 0.0

    def __post_init__(self) -> None:
        _face(self.face)


@dataclass(frozen=True)
class FaceClamp:
    """Clamped face: every displacement component (and automaton rotation) is zero."""

    face: str

    def __post_init__(self) -> None:
        _face(self.face)


TemperatureConstraint = PointTemperature | PatchTemperature | FaceTemperature
Support = FaceSupport | FaceClamp
Constraint = TemperatureConstraint | Support


def point_patch_note(constraints: tuple[Any, ...] | list[Any], spacing: float) -> str:
    """The status note of a discretisation whose nodes are `spacing` apart when a temperature patch is smaller
    than that: it then holds only the node at its centre, a point constraint, not the patch."""
    small = sorted({c.radius for c in constraints if isinstance(c, PatchTemperature) and c.radius < spacing})
    if not small:
        return ""
    return (f"patch radius rho={small[0]:.3g} m is below the node spacing {spacing:.3g} m: each such patch holds "
            "only the node at its centre (a point constraint)")
