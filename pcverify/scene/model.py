"""The scene: an immutable, validated value that says what is simulated.

A scene declares its geometry (`Box`), material, constraints, the physics it needs and one part per
physics: `Conduction` (temperature scale, steady or transient, volumetric source, interface flux),
`Elasticity` (eigenfrequencies asked for, loading rate, response function) and `Contact` (two bodies across
a plane, pressed, possibly sliding and heated by friction).  New physics adds a part; it does not
grow the scene.  Solvers read what a scene declares, never its name.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .constraints import Constraint, FaceClamp, FaceSupport, PatchTemperature, PointTemperature, TemperatureConstraint
from .contact import Contact
from .geometry import Box
from .loads import InterfaceFlux, SineSource
from .material import Material, Response
from .params import SceneError, is_real, shown

PHYSICS = {
    "conduction": "heat conduction (a Conduction part)",
    "heat-source": "a volumetric heat source (Conduction.source != 0)",
    "heat-source-field": "a spatially varying volumetric heat source (Conduction.source_field not empty)",
    "interface-flux": "a planar heat source on an internal plane (Conduction.interface with flux != 0)",
    "elasticity": "linear elasticity (an Elasticity part)",
    "modes": "eigenfrequencies (Elasticity.modes >= 1)",
    "fracture": "loading to failure with a response function (Elasticity.response, strain_rate > 0)",
    "contact": "two bodies touching across a plane, pressed and possibly sliding (a Contact part)",
    "frictional-heating": "the power dissipated by friction heats the bodies (Contact.heating, with conduction)",
    "stick-slip": "body 2 pulled along the contact by a spring, static and kinetic friction (Contact.spring_stiffness)",
    "incline": "body 2 under its own tilted weight on body 1, static and kinetic friction (Contact.incline_angle)",
}
MODES = ("steady", "transient")
MAX_SOURCE_TERMS = 8


def _finite(name: str, v: Any, low: float, high: float, unit: str, low_open: bool = False) -> None:
    ok = is_real(v)
    ok = ok and (v > low if low_open else v >= low) and v <= high
    if not ok:
        span = f"{'(' if low_open else '['}{low:g}, {high:g}] {unit}".rstrip()
        raise SceneError(f"{name}={shown(v)} is out of range; allowed: number in {span}")


@dataclass(frozen=True)
class Conduction:
    """Heat conduction: temperatures are reported as T / t_max; a transient starts from
    `initial_temperature` and is reported at `t_end` (continuum solvers step with `dt`); `source` is a
    uniform volumetric heat source in W/m^3, `source_field` a varying one added to it (a sum of at most
    MAX_SOURCE_TERMS `SineSource` terms); `interface` a planar source on an internal plane (W/m^2)."""

    t_max: float = 500.0
    mode: str = "steady"
    t_end: float = 0.0
    dt: float = 0.0
    initial_temperature: float = 0.0
    source: float = 0.0
    interface: InterfaceFlux | None = None
    source_field: tuple[SineSource, ...] = ()

    def __post_init__(self) -> None:
        _finite("t_max", self.t_max, 0.0, 1e6, "K", low_open=True)
        terms = self.source_field
        if not (isinstance(terms, tuple) and len(terms) <= MAX_SOURCE_TERMS
                and all(isinstance(t, SineSource) for t in terms)):
            raise SceneError(f"source_field={shown(terms)} is not valid; allowed: a tuple of at most "
                             f"{MAX_SOURCE_TERMS} SineSource terms")
        if self.interface is not None and not isinstance(self.interface, InterfaceFlux):
            raise SceneError(f"interface={shown(self.interface)} is not valid; allowed: an InterfaceFlux or none")
        if self.mode not in MODES:
            raise SceneError(f"mode={shown(self.mode)} is not allowed; allowed: {', '.join(MODES)}")
        _finite("initial_temperature", self.initial_temperature, 0.0, 1e6, "K")
        _finite("source", self.source, -1e15, 1e15, "W/m^3")
        if self.mode == "transient":
            _finite("t_end", self.t_end, 0.0, 1e6, "s", low_open=True)
            if not (is_real(self.dt) and 0 < self.dt <= self.t_end):
                raise SceneError(f"dt={shown(self.dt)} is out of range; allowed: number in (0, t_end={self.t_end:g}] s")

    def source_at(self, points: np.ndarray) -> np.ndarray:
        """The volumetric heat source (W/m^3) at points of shape (k, 3): the uniform `source` plus the field."""
        pts = np.asarray(points, dtype=float).reshape(-1, 3)
        return sum((t.at(pts) for t in self.source_field), np.full(len(pts), float(self.source)))


@dataclass(frozen=True)
class Elasticity:
    """Linear elasticity: `modes` eigenfrequencies asked for (0: none); fracture scenes load at the
    nominal axial strain rate `strain_rate` (1/s) until failure with `response`."""

    modes: int = 0
    strain_rate: float = 0.0
    response: Response | None = None

    def __post_init__(self) -> None:
        if isinstance(self.modes, bool) or not isinstance(self.modes, int) or not 0 <= self.modes <= 1000:
            raise SceneError(f"modes={shown(self.modes)} is out of range; allowed: integer in [0, 1000]")
        _finite("strain_rate", self.strain_rate, 0.0, 1e6, "1/s")


@dataclass(frozen=True)
class Scene:
    """One simulated situation, validated at construction.

    `physics` names what a solver must be able to do (words of PHYSICS); each word's part must be
    given and consistent with it.  `params` holds the effective catalogue parameters that built it.
    """

    name: str
    description: str
    box: Box
    material: Material
    physics: frozenset[str]
    constraints: tuple[Constraint, ...]
    conduction: Conduction | None = None
    elasticity: Elasticity | None = None
    params: tuple[tuple[str, Any], ...] = field(default=())
    contact: Contact | None = None

    def __post_init__(self) -> None:
        unknown = sorted(set(self.physics) - set(PHYSICS))
        if unknown:
            raise SceneError(f"physics={unknown[0]!r} is unknown; allowed: {', '.join(PHYSICS)}")
        self._check_part("conduction", self.conduction, Conduction)
        self._check_part("elasticity", self.elasticity, Elasticity)
        self._check_part("contact", self.contact, Contact)
        cond, el = self.conduction, self.elasticity
        derived = {"heat-source": cond is not None and cond.source != 0.0,
                   "heat-source-field": cond is not None and bool(cond.source_field),
                   "interface-flux": cond is not None and cond.interface is not None and cond.interface.flux != 0.0,
                   "modes": el is not None and el.modes > 0,
                   "fracture": el is not None and el.response is not None and el.strain_rate > 0,
                   "frictional-heating": self.contact is not None and self.contact.heating,
                   "stick-slip": self.contact is not None and self.contact.spring_stiffness is not None,
                   "incline": self.contact is not None and self.contact.incline_angle is not None}
        for word, present in derived.items():
            if present != (word in self.physics):
                raise SceneError(f"physics {sorted(self.physics)} and the scene's parts disagree on {word!r}: "
                                 f"allowed: {word!r} in physics exactly when the scene has {PHYSICS[word]}")
        if cond is not None:
            self.material.require("conductivity", "heat_capacity")
            plane = cond.interface
            if plane is not None and not 0.0 < plane.position < self.box.extent[plane.axis_index]:
                span = self.box.extent[plane.axis_index]
                raise SceneError(f"interface position={plane.position!r} is out of range; allowed: number in (0, "
                                 f"{span:g}) m (inside the body along {plane.axis})")
        if el is not None:
            self.material.require("youngs_modulus", "poisson_ratio")
        if self.contact is not None:
            self._check_contact(self.contact)
        for k, c in enumerate(self.constraints):
            self._check_position(k, c)
            heat = isinstance(c, TemperatureConstraint)
            if heat and cond is None or isinstance(c, (FaceSupport, FaceClamp)) and el is None:
                raise SceneError(f"constraint {type(c).__name__} needs the {'conduction' if heat else 'elasticity'} "
                                 "physics, which the scene does not have")

    def _check_position(self, k: int, c: Any) -> None:
        """A point constraint's point, or a patch's centre, lies in the body (the closed box): the same check
        for every solver, before any of them runs."""
        if isinstance(c, PointTemperature):
            where, what = c.point, "point"
        elif isinstance(c, PatchTemperature):
            where, what = c.centre, "centre"
        else:
            return
        if not self.box.holds(where):
            raise SceneError(f"constraint {k + 1} ({type(c).__name__}) {what}={shown(where)} m lies outside the "
                             f"body; allowed: a point in the box [0, {self.box.width:g}] x [0, {self.box.height:g}] "
                             f"x [0, {self.box.length:g}] m")

    def _check_contact(self, contact: Contact) -> None:
        """The interface lies inside the box, body 2's span along the sliding direction too; heating needs
        conduction, and a contact needs elasticity."""
        if self.elasticity is None:
            raise SceneError("contact needs the elasticity physics, which the scene does not have")
        if contact.heating and self.conduction is None:
            raise SceneError("frictional heating needs the conduction physics, which the scene does not have")
        span = float(self.box.extent[contact.axis_index])
        if not contact.position < span:
            raise SceneError(f"contact position={contact.position!r} is out of range; allowed: number in (0, {span:g})"
                             f" m (inside the box along {contact.axis})")
        if contact.span is not None:
            length = float(self.box.extent[contact.direction_index])
            if contact.span[1] > length * (1 + 1e-12):
                raise SceneError(f"contact span={contact.span!r} is out of range; allowed: inside [0, {length:g}] m "
                                 f"along {contact.direction}")

    def _check_part(self, word: str, part: Any, kind: type) -> None:
        if (word in self.physics) != (part is not None) or (part is not None and not isinstance(part, kind)):
            raise SceneError(f"{word}: the scene's physics says {word in self.physics} but its {word} part is "
                             f"{type(part).__name__}; allowed: a {kind.__name__} exactly when {word!r} is in physics")

    @property
    def param_dict(self) -> dict[str, Any]:
        return dict(self.params)

    @property
    def quantity(self) -> str:
        """What a solution of the scene samples: the displacement (a mode's shape) of an elastic scene, else the
        relative temperature; a record without a solution (failed, skipped) says this."""
        if self.elasticity is not None:
            return "mode-1 shape (max |u| = 1)" if self.elasticity.modes else "u (m)"
        return "T/t_max"

    def sample_sets(self, n: int) -> dict[str, np.ndarray]:
        """Sample points at resolution n: lattice nodes and the paper's two edges (front top: x = 0, y = H;
        bottom back: x = W, y = 0), the edges at the lattice's z levels.  Only points in the material: a
        contact's slider shorter than its base leaves out the lattice points beside it.  A solver reports its
        values at exactly these points (the harness checks them)."""
        nodes = self.box.lattice_points(n)
        z = np.linspace(0.0, self.box.length, self.box.lattice_shape(n)[2])
        zeros = np.zeros_like(z)
        front_top = np.stack([zeros, zeros + self.box.height, z], axis=1)
        bottom_back = np.stack([zeros + self.box.width, zeros, z], axis=1)
        sets = {"nodes": nodes, "front_top_edge": front_top, "bottom_back_edge": bottom_back}
        if self.contact is not None:
            sets = {k: v[self.contact.occupied(v, self.box.extent)] for k, v in sets.items()}
        return sets

    def content_hash(self) -> str:
        """Stable hash of everything that defines the scene (not of Python object ids): the cache's identity of
        the scene as it was given, recipe (`params`) included."""
        return _digest(_plain(self))

    def solver_input_hash(self) -> str:
        """Stable hash of what a solver reads from the scene: its content without the recipe that built it
        (name, description, the catalogue's `params`) and without what its own mode ignores (a steady
        conduction's t_end, dt and initial temperature: the steady field does not depend on them).  Scenes with
        the same solver input hash are the same problem to every solver; the calibration's overlap guard
        compares it, so a held-out cell that differs from a fitted one only in what no solver reads is refused."""
        plain = _plain(self)
        for key in ("name", "description", "params"):
            plain.pop(key)
        heat = plain.get("conduction")
        if isinstance(heat, dict) and heat.get("mode") == "steady":
            heat.update(t_end=repr(0.0), dt=repr(0.0), initial_temperature=repr(0.0))
        return _digest(plain)


def _digest(plain: Any) -> str:
    payload = json.dumps(plain, sort_keys=True, default=str)
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def _plain(obj: Any) -> Any:
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        fields = {f.name: _plain(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
        return {"type": type(obj).__name__, **fields}
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (set, frozenset)):
        return sorted(_plain(v) for v in obj)
    if isinstance(obj, float):
        return repr(obj)
    return obj
