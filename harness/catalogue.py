"""The catalogue of named scenes: parameters (default, range, unit) and a builder each.

A new scene is one `SceneSpec` entry: data plus the function that turns effective
parameter values into a `Scene`.  See PHYSICS.md §2 for the three bar-heating variants.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pcverify.harness.scene import (
    ALUMINIUM,
    DURALUMIN,
    RESPONSES,
    Box,
    Conduction,
    Elasticity,
    FaceClamp,
    FaceSupport,
    FaceTemperature,
    Param,
    PatchTemperature,
    PointTemperature,
    Response,
    Scene,
    SceneError,
    resolve_params,
)

BOX = Box()  # the paper's bar, 0.01 x 0.01 x 0.03 m (the default dimensions of every catalogue scene)
PLACEMENTS = ("back-edge", "diagonal")

DIMENSIONS = (
    Param("width", BOX.width, "m", "box width (x); the lattice spacing is a = width / (n - 1)", low=0.0, high=1.0,
          low_open=True),
    Param("height", BOX.height, "m", "box height (y): a whole number of spacings at the resolutions used",
          low=0.0, high=1.0, low_open=True),
    Param("length", BOX.length, "m", "box length (z): a whole number of spacings at the resolutions used",
          low=0.0, high=1.0, low_open=True),
)
T_MAX = Param("t_max", 500.0, "K", "hot temperature (relative results are T/t_max)", low=1e-3, high=1e5)
PLACEMENT = Param("placement", "back-edge", "", "which two bottom corners are frozen", choices=PLACEMENTS, kind=str)


def box_of(p: dict[str, Any]) -> Box:
    """The box of the effective parameters `p` (width, height, length)."""
    return Box(p["width"], p["height"], p["length"])


def corners(box: Box, placement: str) -> list[tuple[tuple[float, float, float], float]]:
    """(point, fraction of t_max) of the paper's three corners: the hot one on the front top edge, (0, H, 0),
    and the two frozen ones on the bottom face (PHYSICS.md §2)."""
    frozen = {"back-edge": ((box.width, 0.0, 0.0), (box.width, 0.0, box.length)),
              "diagonal": ((box.width, 0.0, 0.0), (0.0, 0.0, box.length))}[placement]
    return [((0.0, box.height, 0.0), 1.0)] + [(c, 0.0) for c in frozen]


@dataclass(frozen=True)
class SceneSpec:
    """A named scene: one-line description, its parameters, and the builder."""

    name: str
    description: str
    parameters: tuple[Param, ...]
    build: Callable[[dict[str, Any]], Scene]

    def make(self, **given: Any) -> Scene:
        values = resolve_params(self.parameters, given, f"scene {self.name!r}")
        return self.build(values)


def _paper(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = tuple(PointTemperature(pt, frac * p["t_max"]) for pt, frac in corners(box, p["placement"]))
    return Scene("bar-heat-paper", CATALOGUE["bar-heat-paper"].description, box, ALUMINIUM,
                 frozenset({"conduction"}), cons, conduction=Conduction(t_max=p["t_max"]),
                 params=tuple(sorted(p.items())))


def _patch(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = tuple(PatchTemperature(pt, p["rho"], frac * p["t_max"]) for pt, frac in corners(box, p["placement"]))
    return Scene("bar-heat-patch", CATALOGUE["bar-heat-patch"].description, box, ALUMINIUM,
                 frozenset({"conduction"}), cons, conduction=Conduction(t_max=p["t_max"]),
                 params=tuple(sorted(p.items())))


def _faces(p: dict[str, Any]) -> Scene:
    if p["mode"] == "transient" and p["dt"] > p["t_end"]:
        raise SceneError(f"dt={p['dt']!r} is out of range; allowed: number in (0, t_end={p['t_end']:g}] s")
    transient = p["mode"] == "transient"
    cons = (FaceTemperature("z0", p["t_max"]), FaceTemperature("zL", 0.0))
    heat = Conduction(t_max=p["t_max"], mode=p["mode"], t_end=p["t_end"] if transient else 0.0,
                      dt=p["dt"] if transient else 0.0, initial_temperature=0.0)
    return Scene("bar-heat-faces", CATALOGUE["bar-heat-faces"].description, box_of(p), ALUMINIUM,
                 frozenset({"conduction"}), cons, conduction=heat, params=tuple(sorted(p.items())))


def _compression(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = (FaceSupport("z0"), FaceSupport("zL", p["strain"] * box.length))
    return Scene("bar-compression", CATALOGUE["bar-compression"].description, box, DURALUMIN,
                 frozenset({"elasticity"}), cons, elasticity=Elasticity(), params=tuple(sorted(p.items())))


def _modes(p: dict[str, Any]) -> Scene:
    return Scene("bar-modes", CATALOGUE["bar-modes"].description, box_of(p), DURALUMIN,
                 frozenset({"elasticity", "modes"}), (FaceClamp("z0"),), elasticity=Elasticity(modes=p["modes"]),
                 params=tuple(sorted(p.items())))


def _fracture(p: dict[str, Any]) -> Scene:
    if p["sigma_d"] >= p["sigma_c"] or p["sigma_y"] >= p["sigma_c"]:
        raise SceneError(f"sigma_d={p['sigma_d']:g}, sigma_y={p['sigma_y']:g} are out of range; "
                         f"allowed: below sigma_c={p['sigma_c']:g} Pa")
    response = Response(p["response"], p["sigma_c"], p["sigma_d"], p["sigma_y"], p["hardening"], p["k"])
    return Scene("bar-tension-fracture", CATALOGUE["bar-tension-fracture"].description, box_of(p), DURALUMIN,
                 frozenset({"elasticity", "fracture"}), (FaceSupport("z0"), FaceSupport("zL")),
                 elasticity=Elasticity(strain_rate=p["strain_rate"], response=response),
                 params=tuple(sorted(p.items())))


CATALOGUE: dict[str, SceneSpec] = {
    spec.name: spec
    for spec in (
        SceneSpec(
            "bar-heat-paper",
            "Steady conduction, insulated bar, hot corner at t_max and two frozen corners at 0 K fixed at "
            "points (the paper's setting; mesh-dependent in 3-D)",
            (*DIMENSIONS, PLACEMENT, T_MAX),
            _paper,
        ),
        SceneSpec(
            "bar-heat-patch",
            "As bar-heat-paper, but each corner temperature is held on a spherical-octant patch of radius "
            "rho (well-posed; mesh-converged reference)",
            (*DIMENSIONS, PLACEMENT, T_MAX, Param("rho", 1e-3, "m", "patch radius", low=0.0, high=4e-3, low_open=True)),
            _patch,
        ),
        SceneSpec(
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
            _faces,
        ),
        SceneSpec(
            "bar-compression",
            "Uniaxial stress of the duralumin bar (E = 70 GPa, nu = 0.33): face z=0 on frictionless supports, "
            "face z=L displaced by strain * L along z, lateral faces free (analytic: sigma = E eps, "
            "lateral strain -nu eps)",
            (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression)", low=-0.01,
                                high=0.0, high_open=True)),
            _compression,
        ),
        SceneSpec(
            "bar-modes",
            "Free vibration of the duralumin bar clamped at z=0: lowest bending, torsion and axial "
            "eigenfrequencies (reference: scikit-fem Q2, converged)",
            (*DIMENSIONS, Param("modes", 8, "", "number of lowest eigenfrequencies reported", low=1, high=50,
                                kind=int)),
            _modes,
        ),
        SceneSpec(
            "bar-tension-fracture",
            "Tension of the duralumin bar to failure: face z=0 on frictionless supports, face z=L pulled "
            "along z at strain_rate; material response function and strengths as given",
            (
                *DIMENSIONS,
                Param("response", "elastic", "", "response function", choices=RESPONSES, kind=str),
                Param("sigma_c", 400e6, "Pa", "strength (fracture stress)", low=0.0, high=1e10, low_open=True),
                Param("sigma_d", 320e6, "Pa", "start of degradation", low=0.0, high=1e10, low_open=True),
                Param("sigma_y", 300e6, "Pa", "yield stress", low=0.0, high=1e10, low_open=True),
                Param("hardening", 7e9, "Pa", "plastic hardening modulus", low=0.0, high=7e10),
                Param("k", 1.0, "", "sigma_c / sigma_t (Drucker-Prager)", low=0.1, high=20.0),
                Param("strain_rate", 10.0, "1/s", "nominal axial strain rate", low=0.0, high=1e4, low_open=True),
            ),
            _fracture,
        ),
    )
}


def scene_names() -> list[str]:
    return list(CATALOGUE)


def make_scene(name: str, **params: Any) -> Scene:
    """Build the named scene with parameter overrides; unknown names or bad values raise SceneError."""
    if not isinstance(name, str) or name not in CATALOGUE:
        raise SceneError(f"scene={name!r} is unknown; allowed: one of {', '.join(CATALOGUE)}")
    return CATALOGUE[name].make(**params)
