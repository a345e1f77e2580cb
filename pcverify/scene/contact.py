"""Contact of two bodies: what a scene declares when two bodies touch and may slide (the physics "contact").

The scene's box is split by the interface plane `position` across `axis` into body 1 (below the plane) and
body 2 (above it); `span`, if given, limits body 2 along the sliding `direction` (a slider shorter than its
base).  Body 2's far face (the box face at the upper end of `axis`) is pressed onto body 1 by the uniform
`normal_stress` and, with `speed` > 0, driven along `direction` for `duration` seconds of sliding.  With
`heating`, the power dissipated by friction enters the two bodies as heat (the physics "frictional-heating",
which needs a Conduction part); `base_conductivity` and `base_heat_capacity` give body 1 thermal constants of
its own (dissimilar blocks: the friction heat then divides between the bodies unevenly; the mechanics is the
scene material's).  Body 1 is held by the scene's constraints (a clamp or supports); body 2's far face by the
drive, or by supports when the contact is only compressed.  With `spring_stiffness`, body 2 is not driven at a
prescribed speed but pulled along `direction` by a spring of that stiffness whose far end moves at `speed` (the
stick-slip drive; its far face carries only the normal stress), and `mu_static`, `mu_kinetic` are the friction
pair of the two surfaces that the analytic stick-slip cycle takes (references/contact.py).  With
`incline_angle`, body 2 carries only its weight under the body force `gravity` (m/s^2) tilted by that angle from
the contact's normal towards `direction` (an incline: the pair mu_static, mu_kinetic decides whether it sticks).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import SceneError, is_real, shown

AXES = ("x", "y", "z")


def _number(name: str, v: object, low: float, high: float, unit: str, low_open: bool = False) -> None:
    ok = is_real(v)
    ok = ok and (v > low if low_open else v >= low) and v <= high
    if not ok:
        raise SceneError(f"{name}={shown(v)} is out of range; allowed: number in {'(' if low_open else '['}{low:g}, "
                         f"{high:g}] {unit}".rstrip())


@dataclass(frozen=True)
class Contact:
    """Two bodies across the plane `position` (m) normal to `axis`; body 2 pressed by `normal_stress` (Pa) and
    slid along `direction` at `speed` (m/s) for `duration` (s); `span` = (low, high) in m along `direction`
    limits body 2 (default: the whole box); `heating`: friction heats the bodies; `platen`: once pressed, body
    2's far face is held at its height along `axis` while it slides (a rigid platen takes the friction's
    moment), instead of staying under the applied stress; `base_conductivity` (W/(m K)) and `base_heat_capacity`
    (J/(kg K)): body 1's thermal constants where they differ from the scene material's (None: the same);
    `spring_stiffness` (N/m): a spring drive instead of the prescribed one (its far end at `speed`);
    `mu_static` >= `mu_kinetic`: the surfaces' static and kinetic friction coefficients (with the spring or the
    incline); `incline_angle` (degrees) and `gravity` (m/s^2): body 2's weight tilted towards `direction`."""

    axis: str = "z"
    position: float = 0.015
    normal_stress: float = 0.0
    speed: float = 0.0
    direction: str = "x"
    duration: float = 0.0
    span: tuple[float, float] | None = None
    heating: bool = False
    platen: bool = False
    base_conductivity: float | None = None
    base_heat_capacity: float | None = None
    spring_stiffness: float | None = None
    mu_static: float | None = None
    mu_kinetic: float | None = None
    incline_angle: float | None = None
    gravity: float | None = None

    def __post_init__(self) -> None:
        for name in ("axis", "direction"):
            if getattr(self, name) not in AXES:
                raise SceneError(f"{name}={shown(getattr(self, name))} is not allowed; allowed: {', '.join(AXES)}")
        if self.direction == self.axis:
            raise SceneError(f"direction={self.direction!r} is not allowed; allowed: an axis other than the "
                             f"contact axis {self.axis!r} (sliding is tangential)")
        _number("position", self.position, 0.0, 1e3, "m", low_open=True)
        _number("normal_stress", self.normal_stress, 0.0, 1e10, "Pa")
        _number("speed", self.speed, 0.0, 1e3, "m/s")
        _number("duration", self.duration, 0.0, 1e3, "s")
        if self.speed > 0 and (self.normal_stress <= 0 or self.duration <= 0):
            raise SceneError(f"normal_stress={self.normal_stress!r}, duration={self.duration!r} are out of range for "
                             "sliding; allowed: both > 0 when speed > 0")
        if self.span is not None:
            ok = isinstance(self.span, tuple) and len(self.span) == 2 and all(
                is_real(v) for v in self.span)
            if not ok or not 0 <= self.span[0] < self.span[1]:
                raise SceneError(f"span={shown(self.span)} is not valid; allowed: (low, high) with 0 <= low < high m")
        for name in ("heating", "platen"):
            if not isinstance(getattr(self, name), bool):
                raise SceneError(f"{name}={shown(getattr(self, name))} is not valid; allowed: true/false")
        for name, unit in (("base_conductivity", "W/(m K)"), ("base_heat_capacity", "J/(kg K)")):
            if getattr(self, name) is not None:
                _number(name, getattr(self, name), 0.0, 1e15, unit, low_open=True)
                if not self.heating:
                    raise SceneError(f"{name}={shown(getattr(self, name))} is not allowed without heating; allowed: "
                                     "body 1's thermal constants of a frictional-heating contact")
        self._check_spring()

    def _check_spring(self) -> None:
        """A spring drive needs a sliding contact (its far end's speed) and the friction pair, mu_static >=
        mu_kinetic; the pair is refused without a spring (nothing reads it)."""
        pair = (self.mu_static, self.mu_kinetic)
        if (self.incline_angle is None) != (self.gravity is None):
            raise SceneError(f"incline_angle={shown(self.incline_angle)}, gravity={shown(self.gravity)} are not "
                             "valid; allowed: both (an incline) or neither")
        if self.incline_angle is not None:
            _number("incline_angle", self.incline_angle, 0.0, 89.0, "degrees")
            _number("gravity", self.gravity, 0.0, 1e9, "m/s^2", low_open=True)
            if self.spring_stiffness is not None or self.sliding or self.normal_stress != 0.0:
                raise SceneError(f"incline_angle={shown(self.incline_angle)} is not allowed with a spring, a speed "
                                 "or a normal_stress; allowed: body 2 under its own weight only")
        elif self.spring_stiffness is None:
            if any(v is not None for v in pair):
                raise SceneError(f"mu_static={shown(self.mu_static)}, mu_kinetic={shown(self.mu_kinetic)} are not "
                                 "allowed without spring_stiffness; allowed: the friction pair of a spring drive or "
                                 "an incline")
            return
        else:
            _number("spring_stiffness", self.spring_stiffness, 0.0, 1e12, "N/m", low_open=True)
            if not self.sliding:
                raise SceneError(f"spring_stiffness={shown(self.spring_stiffness)} is not allowed without speed; "
                                 "allowed: a spring drive whose far end moves at speed > 0")
        _number("mu_kinetic", self.mu_kinetic, 0.0, 5.0, "")
        _number("mu_static", self.mu_static, 0.0, 5.0, "")
        if self.mu_static < self.mu_kinetic:
            raise SceneError(f"mu_static={shown(self.mu_static)} is out of range; allowed: number in "
                             f"[mu_kinetic={self.mu_kinetic:g}, 5]")

    @property
    def axis_index(self) -> int:
        return AXES.index(self.axis)

    @property
    def direction_index(self) -> int:
        return AXES.index(self.direction)

    @property
    def sliding(self) -> bool:
        return self.speed > 0.0

    def occupied(self, points: np.ndarray, extent: np.ndarray) -> np.ndarray:
        """Mask of the `points` (k, 3) that lie in one of the two bodies: body 1 fills the box below the plane,
        body 2 the box above it within `span` along `direction` (ends included, to 1e-9 of the box along it)."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        if self.span is None:
            return np.ones(len(pts), dtype=bool)
        upper = pts[:, self.axis_index] > self.position
        along = pts[:, self.direction_index]
        tol = 1e-9 * float(extent[self.direction_index])
        return ~upper | ((along >= self.span[0] - tol) & (along <= self.span[1] + tol))
