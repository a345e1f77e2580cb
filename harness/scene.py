"""Scene model: the vocabulary that solvers consume.

A scene is an immutable, validated value: geometry, material, constraints, time
settings and the sample points every solver reports at.  This module imports
nothing else of the harness, so solvers may import it (and only it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

Vec3 = tuple[float, float, float]

SAMPLE_SETS = ("nodes", "front_top_edge", "bottom_back_edge")
FACES = ("x0", "xW", "y0", "yH", "z0", "zL")


class SceneError(ValueError):
    """A scene or solver parameter outside its allowed range (message names it)."""


@dataclass(frozen=True)
class Param:
    """Specification of one named parameter: default, unit, allowed range or choices."""

    name: str
    default: Any
    unit: str = ""
    description: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    choices: tuple[Any, ...] | None = None
    kind: type = float
    optional: bool = False  # None is an allowed value

    def allowed(self) -> str:
        """Human-readable allowed range, used in every error message."""
        if self.choices is not None:
            return "one of " + ", ".join(str(c) for c in self.choices)
        lo = "-inf" if self.low is None else f"{self.low:g}"
        hi = "inf" if self.high is None else f"{self.high:g}"
        left = "(" if (self.low is None or self.low_open) else "["
        right = ")" if (self.high is None or self.high_open) else "]"
        what = {int: "integer", float: "number", bool: "true/false", str: "text"}[self.kind]
        suffix = " or none" if self.optional else ""
        return f"{what} in {left}{lo}, {hi}{right}{' ' + self.unit if self.unit else ''}{suffix}"

    def parse(self, text: str) -> Any:
        """Convert a command-line string to this parameter's type, then check it."""
        if self.optional and text.strip().lower() in ("none", "null", ""):
            return None
        try:
            if self.kind is bool:
                low = text.strip().lower()
                if low not in ("true", "false", "1", "0", "yes", "no", "on", "off"):
                    raise ValueError(text)
                value: Any = low in ("true", "1", "yes", "on")
            elif self.kind is int:
                value = int(text)
            elif self.kind is float:
                value = float(text)
            else:
                value = text
        except ValueError:
            raise SceneError(f"{self.name}={_show(text)} is not valid; allowed: {self.allowed()}") from None
        return self.check(value)

    def check(self, value: Any) -> Any:
        """Return the value (coerced to the declared kind) or raise SceneError."""
        if value is None and self.optional:
            return None
        bad = SceneError(f"{self.name}={_show(value)} is out of range; allowed: {self.allowed()}")
        if self.choices is not None:
            try:
                if not any(isinstance(value, type(c)) and value == c for c in self.choices):
                    raise bad
            except (TypeError, ValueError):  # e.g. an array: ambiguous truth value
                raise bad from None
            return value
        if self.kind is bool:
            if not isinstance(value, (bool, np.bool_)):
                raise bad
            return bool(value)
        if self.kind is str:
            if not isinstance(value, str):
                raise bad
            return value
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise bad
        try:
            number = float(value)
        except OverflowError:  # an int beyond the float range
            raise bad from None
        if not math.isfinite(number):
            raise bad
        if self.kind is int:
            if isinstance(value, (float, np.floating)) and not number.is_integer():
                raise bad
            value = int(value)
        else:
            value = number
        if self.low is not None and (value < self.low or (self.low_open and value == self.low)):
            raise bad
        if self.high is not None and (value > self.high or (self.high_open and value == self.high)):
            raise bad
        return value


def _show(value: Any) -> str:
    """repr of a value for an error message, shortened (a hostile value may be huge or unprintable)."""
    try:
        text = repr(value)
    except Exception:  # noqa: BLE001 - e.g. an int beyond the str conversion limit
        text = f"<{type(value).__name__}>"
    text = " ".join(text.split())
    return text if len(text) <= 60 else text[:57] + "..."


def resolve_params(specs: tuple[Param, ...], given: dict[str, Any], owner: str) -> dict[str, Any]:
    """Effective values of `specs` given overrides; unknown names are an error."""
    names = {p.name for p in specs}
    unknown = sorted(set(given) - names)
    if unknown:
        raise SceneError(
            f"unknown parameter {unknown[0]!r} for {owner}; known: {', '.join(sorted(names)) or 'none'}"
        )
    return {p.name: p.check(given[p.name]) if p.name in given else p.default for p in specs}


@dataclass(frozen=True)
class Resolution:
    """Lattice resolution n (n x n x (3n - 2) nodes) and, for grids, an integer refinement."""

    n: int
    refine: int = 1

    def __post_init__(self) -> None:
        for name, low in (("n", 2), ("refine", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not low <= v <= 1000:
                raise SceneError(f"{name}={v!r} is out of range; allowed: integer in [{low}, 1000]")

    def spacing(self, width: float) -> float:
        """Grid spacing h = a / refine with a = width / (n - 1)."""
        return width / (self.n - 1) / self.refine


@dataclass(frozen=True)
class Material:
    """Material constants in SI units; NaN where a scene does not need one."""

    name: str
    density: float
    conductivity: float = math.nan
    heat_capacity: float = math.nan
    youngs_modulus: float = math.nan
    poisson_ratio: float = math.nan

    @property
    def diffusivity(self) -> float:
        """Thermal diffusivity k / (rho c) in m^2/s."""
        return self.conductivity / (self.density * self.heat_capacity)


ALUMINIUM = Material("aluminium", density=2700.0, conductivity=237.0, heat_capacity=897.0)
DURALUMIN = Material("duralumin", density=2800.0, youngs_modulus=70e9, poisson_ratio=0.33)


@dataclass(frozen=True)
class Box:
    """The bar: x across (width), y vertical (height), z along (length)."""

    width: float = 0.01
    height: float = 0.01
    length: float = 0.03

    @property
    def extent(self) -> np.ndarray:
        return np.array([self.width, self.height, self.length])

    @property
    def volume(self) -> float:
        return self.width * self.height * self.length


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


@dataclass(frozen=True)
class FaceTemperature:
    """Temperature prescribed on a whole face: one of FACES (x0, xW, y0, yH, z0, zL)."""

    face: str
    value: float


@dataclass(frozen=True)
class FaceSupport:
    """Frictionless support: the face's normal displacement is held at `displacement` (m, along the
    outward axis direction of +x/+y/+z), its tangential motion is free."""

    face: str
    displacement: float = 0.0


@dataclass(frozen=True)
class FaceClamp:
    """Clamped face: every displacement component (and automaton rotation) is zero."""

    face: str


RESPONSES = ("elastic", "degradation", "plastic", "plastic-degradation")


@dataclass(frozen=True)
class Response:
    """Uniaxial response function sigma = f(eps) of the material (PHYSICS.md §4, Fig. 3 of seed 001).

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


Constraint = PointTemperature | PatchTemperature | FaceTemperature | FaceSupport | FaceClamp


def lattice_shape(n: int) -> tuple[int, int, int]:
    """Nodes per axis of the simple-cubic lattice family: n x n x (3n - 2)."""
    return (n, n, 3 * n - 2)


def lattice_points(box: Box, n: int) -> np.ndarray:
    """Lattice nodes of resolution n, shape (N, 3), ordered x slowest, z fastest.

    Node (i, j, k) has index (i * ny + j) * nz + k.  Spacing a = width / (n - 1).
    """
    if int(n) != n or n < 2:
        raise SceneError(f"n={n!r} is out of range; allowed: integer >= 2")
    nx, ny, nz = lattice_shape(n)
    axes = [np.linspace(0.0, ext, cnt) for ext, cnt in zip(box.extent, (nx, ny, nz), strict=True)]
    grid = np.meshgrid(*axes, indexing="ij")
    return np.stack([g.ravel() for g in grid], axis=1)


def lattice_spacing(box: Box, n: int) -> float:
    """Spacing a of the lattice of resolution n."""
    return box.width / (n - 1)


@dataclass(frozen=True)
class Scene:
    """One simulated situation, validated at construction.

    `physics` names what a solver must be able to do (e.g. {"conduction"}).
    `mode` is "steady" or "transient"; a transient scene starts from
    `initial_temperature` and is reported at `t_end` (continuum solvers step with `dt`).
    `t_max` scales reported temperatures: solutions report T / t_max.
    `params` holds the effective catalogue parameters that built the scene.
    Elasticity scenes (physics contains "elasticity") hold FaceSupport / FaceClamp constraints;
    "modes" asks for eigenfrequencies (`modes` of them); "fracture" loads at `strain_rate` (1/s, the
    nominal axial strain rate of a FaceSupport's displacement) until failure with `response`.
    """

    name: str
    description: str
    box: Box
    material: Material
    physics: frozenset[str]
    constraints: tuple[Constraint, ...]
    t_max: float = 500.0
    mode: str = "steady"
    t_end: float = 0.0
    dt: float = 0.0
    initial_temperature: float = 0.0
    response: Response | None = None
    modes: int = 0
    strain_rate: float = 0.0
    params: tuple[tuple[str, Any], ...] = field(default=())

    def __post_init__(self) -> None:
        if self.mode not in ("steady", "transient"):
            raise SceneError(f"mode={self.mode!r} is not allowed; allowed: steady, transient")
        for name in ("width", "height", "length"):
            v = getattr(self.box, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise SceneError(f"box.{name}={v!r} is out of range; allowed: number in (0, inf) m")
        if not (math.isfinite(self.t_max) and self.t_max > 0):
            raise SceneError(f"t_max={self.t_max!r} is out of range; allowed: number in (0, inf) K")
        if self.mode == "transient":
            if not (math.isfinite(self.t_end) and self.t_end > 0):
                raise SceneError(f"t_end={self.t_end!r} is out of range; allowed: number in (0, inf) s")
            if not (math.isfinite(self.dt) and 0 < self.dt <= self.t_end):
                raise SceneError(f"dt={self.dt!r} is out of range; allowed: number in (0, t_end={self.t_end:g}] s")
        for c in self.constraints:
            if isinstance(c, (FaceTemperature, FaceSupport, FaceClamp)) and c.face not in FACES:
                raise SceneError(f"face={c.face!r} is not allowed; allowed: {', '.join(FACES)}")
            if isinstance(c, PatchTemperature) and not (math.isfinite(c.radius) and c.radius > 0):
                raise SceneError(f"rho={c.radius!r} is out of range; allowed: number in (0, inf) m")

        if self.response is not None and self.response.kind not in RESPONSES:
            raise SceneError(f"response={self.response.kind!r} is not allowed; allowed: {', '.join(RESPONSES)}")

    @property
    def param_dict(self) -> dict[str, Any]:
        return dict(self.params)

    def sample_sets(self, n: int) -> dict[str, np.ndarray]:
        """Sample points at resolution n: lattice nodes and the paper's two edges."""
        nodes = lattice_points(self.box, n)
        z = np.linspace(0.0, self.box.length, lattice_shape(n)[2])
        zeros = np.zeros_like(z)
        front_top = np.stack([zeros, zeros + self.box.height, z], axis=1)
        bottom_back = np.stack([zeros + self.box.width, zeros, z], axis=1)
        return {"nodes": nodes, "front_top_edge": front_top, "bottom_back_edge": bottom_back}

    def content_hash(self) -> str:
        """Stable hash of everything that defines the scene (not of Python object ids)."""
        payload = json.dumps(_plain(self), sort_keys=True, default=str)
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
