"""The heat family: the three bar-heating scenes (docs/physics.md, "The heating scenes") and the manufactured
solution heat-manufactured, their references and the summary scalars a heat solver reports.  Its field
reference (`analytic`, exact T / t_max) is the slab along one axis (held or insulated faces, a uniform source, a
planar flux), summed to a bounded tail, and the semi-infinite solid's rise and effusivity shares for short times
(docs/physics.md, "Analytic references", "Heat flowing along one axis (the slab)").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from pcverify.references.shared import DIMENSIONS, T_MAX, box_of
from pcverify.scene import (
    ALUMINIUM,
    Box,
    Conduction,
    FaceTemperature,
    Param,
    PatchTemperature,
    PointTemperature,
    Reference,
    Scalar,
    Scene,
    SceneError,
    SceneSpec,
    SineSource,
    TemperatureConstraint,
)
from pcverify.scene import (
    FACES as BOX_FACES,
)

ERFC = np.vectorize(math.erfc, otypes=[float])  # numpy only: the scene catalogue imports no scipy
MAX_TERMS = 2_000_000  # a guard against t -> 0 (the series then needs ~sqrt(ln(B/tol)/c) terms)


def terms_needed(c: float, bound: float, tol: float) -> int:
    """Terms K of sum_m (B/m) e^{-c m^2} after which the tail is below tol (c > 0)."""
    if not c > 0:
        raise ValueError(f"c={c!r} is out of range; allowed: number in (0, inf) (t > 0)")
    if bound <= 0:
        return 0
    k = max(1, int(math.sqrt(max(math.log(bound / tol), 0.0) / c)) - 1)
    while k < MAX_TERMS:
        tail = bound / (k + 1) * math.exp(-c * (k + 1) ** 2) / (1.0 - math.exp(-c * (2 * k + 3)))
        if tail < tol:
            return k
        k += 1
    raise ValueError(f"the series needs more than {MAX_TERMS} terms at c={c:g}; allowed: a later time")


@dataclass(frozen=True)
class Slab:
    """Heat flow across 0 <= z <= length (the slab: docs/physics.md, "Analytic references"); temperatures in K."""

    length: float
    conductivity: float
    diffusivity: float
    held: tuple[float, float] | None = None
    initial: float = 0.0
    source: float = 0.0
    flux: float = 0.0
    plane: float = 0.0

    def __post_init__(self) -> None:
        if self.flux != 0.0 and not 0.0 < self.plane < self.length:
            raise ValueError(f"plane={self.plane!r} is out of range; allowed: number in (0, {self.length:g}) m")

    def _coefficient_bound(self, held: bool) -> float:
        k, L = self.conductivity, self.length
        plane = 2.0 * abs(self.flux) * L / (k * math.pi**2)
        if not held:
            return plane
        t0, tl = self.held
        return (4.0 * abs(self.initial - t0) + 2.0 * abs(tl - t0)) / math.pi \
            + 2.0 * abs(self.source) * L**2 / (k * math.pi**3) + plane

    def steady(self, z: np.ndarray) -> np.ndarray:
        """Steady T(z) between held faces (ValueError for insulated faces: there is none with a load)."""
        if self.held is None:
            raise ValueError("held=None: an insulated slab has no steady state; allowed: held face temperatures")
        z = np.asarray(z, dtype=float)
        k, L = self.conductivity, self.length
        t0, tl = self.held
        out = t0 + (tl - t0) * z / L + self.source * z * (L - z) / (2.0 * k)
        if self.flux != 0.0:
            zp = self.plane
            green = np.where(z <= zp, z * (L - zp) / L, zp * (L - z) / L)
            out = out + self.flux / k * green
        return out

    def transient(self, z: np.ndarray, t: float, tol: float = 1e-12) -> np.ndarray:
        """T(z, t) from the uniform initial temperature, accurate to `tol` K."""
        if not t > 0:
            raise ValueError(f"t={t!r} is out of range; allowed: number in (0, inf) s")
        z = np.asarray(z, dtype=float)
        k, L, alpha = self.conductivity, self.length, self.diffusivity
        held = self.held is not None
        c = alpha * math.pi**2 * t / L**2
        kmax = terms_needed(c, self._coefficient_bound(held), tol)
        m = np.arange(1, kmax + 1, dtype=float)
        decay = np.exp(-c * m**2)
        if held:
            t0, tl = self.held
            odd = 1.0 - (-1.0) ** m
            b = (2.0 * (self.initial - t0) * odd / (m * math.pi) - 2.0 * (tl - t0) * (-1.0) ** (m + 1) / (m * math.pi)
                 - 2.0 * self.source * L**2 * odd / (k * m**3 * math.pi**3)
                 - 2.0 * self.flux * L * np.sin(m * math.pi * self.plane / L) / (k * m**2 * math.pi**2))
            return self.steady(z) + np.sin(np.multiply.outer(z, m) * math.pi / L) @ (b * decay)
        out = self.initial + (self.source + self.flux / L) * t * alpha / k + 0.0 * z
        if self.flux != 0.0:
            a, b = self.plane / L, z / L
            out = out + self.flux * L / (k * math.pi**2) * (_cos_series(math.pi * np.abs(a - b))
                                                            + _cos_series(math.pi * (a + b)))
            coef = 2.0 * self.flux * L / (k * m**2 * math.pi**2) * np.cos(m * math.pi * a) * decay
            out = out - np.cos(np.multiply.outer(z, m) * math.pi / L) @ coef
        return out


def _cos_series(theta: np.ndarray) -> np.ndarray:
    """sum_{m >= 1} cos(m theta) / m^2 for 0 <= theta <= 2 pi."""
    return math.pi**2 / 6.0 - math.pi * theta / 2.0 + theta**2 / 4.0


def semi_infinite_rise(flux: float, conductivity: float, diffusivity: float, t: float,
                       depth: np.ndarray | float = 0.0) -> np.ndarray:
    """Temperature rise at `depth` below the surface of a semi-infinite solid taking `flux` W/m^2 from t = 0."""
    x = np.asarray(depth, dtype=float)
    root = math.sqrt(diffusivity * t)
    u = x / (2.0 * root)
    ierfc = np.exp(-u * u) / math.sqrt(math.pi) - u * ERFC(u)
    return 2.0 * flux / conductivity * root * ierfc


def effusivity(conductivity: float, density: float, heat_capacity: float) -> float:
    """Thermal effusivity sqrt(k rho c) in W s^0.5 / (m^2 K)."""
    return math.sqrt(conductivity * density * heat_capacity)


def effusivity_shares(e1: float, e2: float) -> tuple[float, float]:
    """Shares of a flux generated between two semi-infinite solids in perfect contact: e_i / (e1 + e2)."""
    return e1 / (e1 + e2), e2 / (e1 + e2)
def slab_of(scene: Scene) -> tuple[Slab, int] | None:
    """The one-dimensional problem a heat scene reduces to, and its axis, or None.

    It does when every temperature constraint is a FaceTemperature and they hold the two faces of one axis
    (or there is none: an insulated body), and an interface flux, if any, lies across that axis; the initial
    temperature is uniform in every scene, the source must be too (no `source_field`).  Not one with dissimilar
    blocks (a contact whose body 1 has thermal constants of its own): the slab is one material.
    """
    heat = scene.conduction
    if heat is None or heat.source_field:
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


FIELD = Reference(field=analytic, kind="analytic")  # also what a study file's [[scene]] gets
SCALARS = (
    Scalar("bulk_median", "", "median of T / t_max over the lattice nodes (the paper's bulk temperature)"),
    Scalar("volume_mean", "", "volume mean of T / t_max"),
)
PLACEMENTS = ("back-edge", "diagonal")
PLACEMENT = Param("placement", "back-edge", "", "which two bottom corners are frozen", choices=PLACEMENTS, kind=str)


def corners(box: Box, placement: str) -> list[tuple[tuple[float, float, float], float]]:
    """(point, fraction of t_max) of the paper's three corners: the hot one on the front top edge, (0, H, 0),
    and the two frozen ones on the bottom face (docs/physics.md, "The heating scenes")."""
    frozen = {"back-edge": ((box.width, 0.0, 0.0), (box.width, 0.0, box.length)),
              "diagonal": ((box.width, 0.0, 0.0), (0.0, 0.0, box.length))}[placement]
    return [((0.0, box.height, 0.0), 1.0)] + [(c, 0.0) for c in frozen]


def _paper(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = tuple(PointTemperature(pt, frac * p["t_max"]) for pt, frac in corners(box, p["placement"]))
    return Scene("bar-heat-paper", PAPER.description, box, ALUMINIUM, frozenset({"conduction"}), cons,
                 conduction=Conduction(t_max=p["t_max"]), params=tuple(sorted(p.items())))


def _patch(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = tuple(PatchTemperature(pt, p["rho"], frac * p["t_max"]) for pt, frac in corners(box, p["placement"]))
    return Scene("bar-heat-patch", PATCH.description, box, ALUMINIUM, frozenset({"conduction"}), cons,
                 conduction=Conduction(t_max=p["t_max"]), params=tuple(sorted(p.items())))


def _faces(p: dict[str, Any]) -> Scene:
    if p["mode"] == "transient" and p["dt"] > p["t_end"]:
        raise SceneError(f"dt={p['dt']!r} is out of range; allowed: number in (0, t_end={p['t_end']:g}] s")
    transient = p["mode"] == "transient"
    cons = (FaceTemperature("z0", p["t_max"]), FaceTemperature("zL", 0.0))
    heat = Conduction(t_max=p["t_max"], mode=p["mode"], t_end=p["t_end"] if transient else 0.0,
                      dt=p["dt"] if transient else 0.0, initial_temperature=0.0)
    return Scene("bar-heat-faces", FACES.description, box_of(p), ALUMINIUM, frozenset({"conduction"}), cons,
                 conduction=heat, params=tuple(sorted(p.items())))


PAPER = SceneSpec(
    "bar-heat-paper",
    "Steady conduction, insulated bar, hot corner at t_max and two frozen corners at 0 K fixed at "
    "points (the paper's setting; mesh-dependent in 3-D)",
    (*DIMENSIONS, PLACEMENT, T_MAX), _paper,  # the bulk's mesh limit: the mean of the corners' fractions (1, 0, 0)
    Reference(scalars=lambda scene, summary: {"bulk_median": 1 / 3}, kind="mesh-dependent"), SCALARS)
PATCH = SceneSpec(
    "bar-heat-patch",
    "As bar-heat-paper, but each corner temperature is held on a spherical-octant patch of radius "
    "rho (well-posed; mesh-converged reference)",
    (*DIMENSIONS, PLACEMENT, T_MAX, Param("rho", 1e-3, "m", "patch radius", low=0.0, high=4e-3, low_open=True)),
    _patch, None, SCALARS)
FACES = SceneSpec(
    "bar-heat-faces",
    "Face z=0 at t_max, face z=L at 0 K, other faces insulated: linear steady profile, "
    "Fourier-series transient from 0 K (analytic reference)",
    (
        *DIMENSIONS,
        T_MAX,
        Param("mode", "steady", "", "steady or transient", choices=("steady", "transient"), kind=str),
        Param("t_end", 1.0, "s", "end time of the transient", low=0.0, high=1e4, low_open=True),
        Param("dt", 0.01, "s", "continuum time step of the transient", low=0.0, high=1e4, low_open=True),
    ),
    _faces, FIELD, SCALARS)

# heat-manufactured (the method of MOOSE's mms module): pick a smooth exact temperature, derive the source it
# implies and hold the boundary at its values; every heat solver must then converge to it at its order.
#     T = t_max sin(mx pi x / W) sin(my pi y / H) sin(mz pi z / L)                 (0 on all six faces)
#     S = -k laplacian(T) = k pi^2 (mx^2 / W^2 + my^2 / H^2 + mz^2 / L^2) T          (W/m^3)
# one SineSource term with the same wave numbers; the integer half-wave counts make it non-symmetric (mx != my
# tells x from y on the square cross-section).

def wavenumbers(scene: Scene) -> tuple[float, float, float]:
    """k_a = m_a pi / extent_a (rad/m) of heat-manufactured's exact temperature."""
    p = scene.param_dict
    return tuple(p[f"m{a}"] * math.pi / float(e) for a, e in zip("xyz", scene.box.extent, strict=True))


def manufactured(scene: Scene, points: np.ndarray) -> np.ndarray:
    """heat-manufactured's exact T / t_max at points of shape (k, 3)."""
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    return np.prod(np.sin(pts * np.asarray(wavenumbers(scene))), axis=1)


def source_amplitude(k: float, t_max: float, wave: tuple[float, float, float]) -> float:
    """Amplitude (W/m^3) of S = -k laplacian(T) for T = t_max prod_a sin(k_a x_a): k t_max sum_a k_a^2."""
    return k * t_max * sum(w * w for w in wave)


def _manufactured(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    wave = tuple(p[f"m{a}"] * math.pi / float(e) for a, e in zip("xyz", box.extent, strict=True))
    term = SineSource(source_amplitude(ALUMINIUM.conductivity, p["t_max"], wave), wave)
    return Scene("heat-manufactured", MANUFACTURED.description, box, ALUMINIUM,
                 frozenset({"conduction", "heat-source-field"}), tuple(FaceTemperature(f, 0.0) for f in BOX_FACES),
                 conduction=Conduction(t_max=p["t_max"], source_field=(term,)), params=tuple(sorted(p.items())))


MANUFACTURED = SceneSpec(
    "heat-manufactured",
    "Steady conduction with the manufactured solution T = t_max sin(mx pi x/W) sin(my pi y/H) sin(mz pi z/L): the "
    "source S = -k laplacian(T) it implies, all six faces at 0 K (analytic reference)",
    (*DIMENSIONS, Param("t_max", 500.0, "K", "amplitude of the exact temperature (relative results are T/t_max)",
                        low=1e-3, high=1e5),
     *(Param(f"m{a}", 1, "", f"half waves of the exact temperature along {a}", low=1, high=8, kind=int)
       for a in "xyz")),
    _manufactured, Reference(field=manufactured, kind="analytic"), SCALARS)
SCENES = (PAPER, PATCH, FACES, MANUFACTURED)
