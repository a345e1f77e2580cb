"""The catalogue of named scenes: the shipped ones, those of installed plugins and those a study defines.

A scene is a `SceneSpec`: parameters (default, range, unit) and the builder that turns their values
into a `Scene`.  Shipped scenes are listed here (the three bar-heating variants: docs/physics.md, "The
heating scenes"); plugin distributions add theirs through the `pcverify.scenes` entry point group (name ->
"module:attribute", the attribute a SceneSpec); plugin modules and study files register theirs at run
time.  Two sources that give the same name are an error that names both.
"""

from __future__ import annotations

import importlib
import math
from typing import Any

from pcverify.harness.spec.schema import SCENE, check
from pcverify.references.manufactured import SPEC as MANUFACTURED
from pcverify.scene import (
    ALUMINIUM,
    DURALUMIN,
    EXTENT_RANGE,
    MATERIALS,
    RESPONSES,
    Box,
    Conduction,
    Contact,
    Elasticity,
    FaceClamp,
    FaceSupport,
    FaceTemperature,
    InterfaceFlux,
    Material,
    Param,
    PatchTemperature,
    PointTemperature,
    Response,
    Scene,
    SceneError,
    SceneSpec,
)
from pcverify.solvers.registry import Entry, Registry

BOX = Box()  # the paper's bar, 0.01 x 0.01 x 0.03 m (the default dimensions of every catalogue scene)
PLACEMENTS = ("back-edge", "diagonal")

DIMENSIONS = (  # the box model's own range (EXTENT_RANGE), so `pcverify scenes` shows what is accepted
    Param("width", BOX.width, "m", "box width (x); the lattice spacing is a = width / (n - 1)", low=EXTENT_RANGE[0],
          high=EXTENT_RANGE[1]),
    Param("height", BOX.height, "m", "box height (y): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
    Param("length", BOX.length, "m", "box length (z): a whole number of spacings at the resolutions used",
          low=EXTENT_RANGE[0], high=EXTENT_RANGE[1]),
)
T_MAX = Param("t_max", 500.0, "K", "hot temperature (relative results are T/t_max)", low=1e-3, high=1e5)
PLACEMENT = Param("placement", "back-edge", "", "which two bottom corners are frozen", choices=PLACEMENTS, kind=str)


def box_of(p: dict[str, Any]) -> Box:
    """The box of the effective parameters `p` (width, height, length)."""
    return Box(p["width"], p["height"], p["length"])


def corners(box: Box, placement: str) -> list[tuple[tuple[float, float, float], float]]:
    """(point, fraction of t_max) of the paper's three corners: the hot one on the front top edge, (0, H, 0),
    and the two frozen ones on the bottom face (docs/physics.md, "The heating scenes")."""
    frozen = {"back-edge": ((box.width, 0.0, 0.0), (box.width, 0.0, box.length)),
              "diagonal": ((box.width, 0.0, 0.0), (0.0, 0.0, box.length))}[placement]
    return [((0.0, box.height, 0.0), 1.0)] + [(c, 0.0) for c in frozen]


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


def _contact_compression(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    cons = (FaceSupport("z0"), FaceSupport("zL", p["strain"] * box.length))
    return Scene("block-contact-compression", CATALOGUE["block-contact-compression"].description, box, DURALUMIN,
                 frozenset({"elasticity", "contact"}), cons, elasticity=Elasticity(),
                 contact=Contact(axis="z", position=box.length / 2), params=tuple(sorted(p.items())))


def _sliding(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    contact = Contact(axis="y", position=box.height / 2, normal_stress=p["normal_stress"], speed=p["speed"],
                      direction="z", duration=p["duration"], span=(box.length / 3, 2 * box.length / 3))
    return Scene("block-sliding", CATALOGUE["block-sliding"].description, box, DURALUMIN,
                 frozenset({"elasticity", "contact"}), (FaceClamp("y0"),), elasticity=Elasticity(), contact=contact,
                 params=tuple(sorted(p.items())))


def _stick_slip(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    contact = Contact(axis="y", position=box.height / 2, normal_stress=p["normal_stress"], speed=p["speed"],
                      direction="z", duration=p["duration"], span=(box.length / 3, 2 * box.length / 3),
                      spring_stiffness=p["spring_stiffness"], mu_static=p["mu_static"], mu_kinetic=p["mu_kinetic"])
    return Scene("stick-slip", CATALOGUE["stick-slip"].description, box, DURALUMIN,
                 frozenset({"elasticity", "contact", "stick-slip"}), (FaceClamp("y0"),), elasticity=Elasticity(),
                 contact=contact, params=tuple(sorted(p.items())))


def _incline(p: dict[str, Any]) -> Scene:
    box = box_of(p)
    contact = Contact(axis="y", position=box.height / 2, direction="z", duration=p["duration"],
                      span=(box.length / 3, 2 * box.length / 3), mu_static=p["mu_static"], mu_kinetic=p["mu_kinetic"],
                      incline_angle=p["angle"], gravity=p["gravity"])
    return Scene("incline", CATALOGUE["incline"].description, box, DURALUMIN,
                 frozenset({"elasticity", "contact", "incline"}), (FaceClamp("y0"),), elasticity=Elasticity(),
                 contact=contact, params=tuple(sorted(p.items())))


# duralumin with its thermal constants (handbook values of 2024, the alloy of the bar's E and nu in
# docs/physics.md, "Conventions")
DURALUMIN_THERMAL = Material("duralumin-2024", density=2800.0, conductivity=121.0, heat_capacity=875.0,
                             youngs_modulus=70e9, poisson_ratio=0.33)
HEAT_SOURCES = ("friction", "flux")


def _frictional_heating(p: dict[str, Any]) -> Scene:
    if p["dt"] > p["t_end"]:
        raise SceneError(f"dt={p['dt']!r} is out of range; allowed: number in (0, t_end={p['t_end']:g}] s")
    box = box_of(p)
    flux = p["friction"] * p["normal_stress"] * p["speed"]
    heat = Conduction(t_max=p["t_max"], mode="transient", t_end=p["t_end"], dt=p["dt"],
                      interface=InterfaceFlux(flux, box.length / 2, "z"))
    physics = {"conduction", "interface-flux"}
    base = {k: p[k] for k in ("base_conductivity", "base_heat_capacity") if p[k] is not None}
    if p["source"] == "flux" and base:
        name = next(iter(base))
        raise SceneError(f"{name}={base[name]!r} is not allowed with source='flux'; allowed: source='friction' (the "
                         "flux scene is one material, as the continuum solvers take it)")
    if p["source"] == "flux":
        return Scene("frictional-heating", CATALOGUE["frictional-heating"].description, box, DURALUMIN_THERMAL,
                     frozenset(physics), (), conduction=heat, params=tuple(sorted(p.items())))
    contact = Contact(axis="z", position=box.length / 2, normal_stress=p["normal_stress"], speed=p["speed"],
                      direction="x", duration=p["duration"], heating=True, platen=True, **base)
    return Scene("frictional-heating", CATALOGUE["frictional-heating"].description, box, DURALUMIN_THERMAL,
                 frozenset(physics | {"elasticity", "contact", "frictional-heating"}), (FaceClamp("z0"),),
                 conduction=heat, elasticity=Elasticity(), contact=contact, params=tuple(sorted(p.items())))


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
            (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression; below 1e-12 in "
                                "magnitude the loads underflow in floating point)", low=-0.01, high=-1e-12)),
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
        SceneSpec(
            "block-contact-compression",
            "Two duralumin blocks stacked along z, unlinked at the interface z = L/2 (contact by the segment method), "
            "compressed between frictionless supports on z=0 and z=L by strain * L (analytic: the uniaxial stress "
            "E |strain| of the bonded bar crosses the interface uniformly); n even",
            (*DIMENSIONS, Param("strain", -1e-3, "", "nominal axial strain (negative = compression)", low=-0.01,
                                high=0.0, high_open=True)),
            _contact_compression,
        ),
        SceneSpec(
            "block-sliding",
            "A duralumin slider (the middle third of the upper half, y > H/2) pressed by normal_stress on a base "
            "(y < H/2, clamped at y=0) and driven along z at speed for duration after a smooth start: the macroscopic "
            "friction coefficient mu_dr = F_dr / F_N (eq. 17) and the energy balance; n even",
            (
                *DIMENSIONS,
                Param("normal_stress", 1e6, "Pa", "pressure on the slider's top face", low=0.0, high=1e9,
                      low_open=True),
                Param("speed", 1.0, "m/s", "sliding speed of the slider's top face", low=0.0, high=100.0,
                      low_open=True),
                Param("duration", 1e-3, "s", "sliding time at full speed (the averaging window)", low=0.0, high=1.0,
                      low_open=True),
            ),
            _sliding,
        ),
        SceneSpec(
            "stick-slip",
            "The block-sliding slider pressed by normal_stress on its clamped base and pulled along z by a spring of "
            "stiffness spring_stiffness whose far end moves at speed (pulling at the slider's centre of mass), with "
            "static and kinetic friction mu_static >= mu_kinetic: the analytic stick-slip cycle of a rigid block "
            "(references/stick_slip.py: peak mu_static N, force drop 2 (mu_static - mu_kinetic) N, period, largest "
            "slip velocity); defaults: the spring's 0.95 kHz far below the slider's lowest elastic frequency (~150 "
            "kHz), 3 cycles after the first in duration; n even",
            (
                *DIMENSIONS,
                Param("normal_stress", 1e6, "Pa", "pressure on the slider's top face", low=0.0, high=1e9,
                      low_open=True),
                Param("speed", 0.5, "m/s", "speed of the spring's far end", low=0.0, high=100.0, low_open=True),
                Param("spring_stiffness", 5e4, "N/m", "stiffness of the drive spring", low=0.0, high=1e12,
                      low_open=True),
                Param("mu_static", 0.4, "", "static friction coefficient of the two surfaces (>= mu_kinetic)",
                      low=0.0, high=5.0),
                Param("mu_kinetic", 0.3, "", "kinetic friction coefficient of the two surfaces", low=0.0, high=5.0),
                Param("duration", 7e-3, "s", "time the spring's far end moves (the whole run after the preload)",
                      low=0.0, high=1.0, low_open=True),
            ),
            _stick_slip,
        ),
        SceneSpec(
            "incline",
            "The block-sliding slider on its clamped base under its own weight only, the body force gravity tilted by "
            "angle from the contact's normal towards +z, friction pair mu_static >= mu_kinetic: a rigid block sticks "
            "while tan(angle) <= mu_static, else slides with the acceleration gravity (sin(angle) - mu_kinetic "
            "cos(angle)) (references/stick_slip.py); gravity is large by default (1e5 m/s^2: the slider's weight "
            "137 N) so that the contact is pressed as in stick-slip; n even",
            (
                *DIMENSIONS,
                Param("angle", 30.0, "degrees", "tilt of the body force from the contact's normal", low=0.0,
                      high=89.0),
                Param("gravity", 1e5, "m/s^2", "magnitude of the body force per mass", low=0.0, high=1e9,
                      low_open=True),
                Param("mu_static", 0.4, "", "static friction coefficient of the two surfaces (>= mu_kinetic)",
                      low=0.0, high=5.0),
                Param("mu_kinetic", 0.3, "", "kinetic friction coefficient of the two surfaces", low=0.0, high=5.0),
                Param("duration", 5e-4, "s", "time the tilted weight acts (after the normal preload)", low=0.0,
                      high=1.0, low_open=True),
            ),
            _incline,
        ),
        SceneSpec(
            "frictional-heating",
            "Two duralumin blocks stacked along z (interface z = L/2, base clamped at z=0), the upper one pressed by "
            "normal_stress and slid along x at speed under a platen: the friction power heats both (MCA mechanics "
            "-> MCA heat, source=friction); the reference is the same bar with the interface flux q = friction * "
            "normal_stress * speed (source=flux: continuum solvers; analytic slab and, at short times, the "
            "semi-infinite rise); insulated faces, from 0 K to t_end; n even",
            (
                *DIMENSIONS,
                Param("source", "friction", "", "friction: MCA's sliding contact makes the heat; flux: the interface "
                      "flux is given (any heat solver)", choices=HEAT_SOURCES, kind=str),
                Param("normal_stress", 1e6, "Pa", "pressure on the upper block's top face", low=0.0, high=1e9,
                      low_open=True),
                Param("speed", 1.0, "m/s", "sliding speed", low=0.0, high=100.0, low_open=True),
                Param("friction", 0.3, "", "friction coefficient of the declared flux q = friction normal_stress "
                      "speed (MCA's own law must dissipate it: its mu1 defaults to the same 0.3)", low=0.0, high=5.0),
                Param("duration", 3e-4, "s", "sliding time at full speed over which the friction power is averaged",
                      low=0.0, high=1.0, low_open=True),
                Param("t_end", 0.5, "s", "heating time", low=0.0, high=1e4, low_open=True),
                Param("dt", 0.005, "s", "continuum time step", low=0.0, high=1e4, low_open=True),
                Param("t_max", 10.0, "K", "temperature scale (relative results are T/t_max)", low=1e-3, high=1e5),
                Param("base_conductivity", None, "W/(m K)", "the lower block's own conductivity (dissimilar blocks, "
                      "source=friction; none = duralumin's 121)", low=0.0, high=1e4, low_open=True, optional=True),
                Param("base_heat_capacity", None, "J/(kg K)", "the lower block's own heat capacity (dissimilar "
                      "blocks, source=friction; none = duralumin's 875)", low=0.0, high=1e5, low_open=True,
                      optional=True),
            ),
            _frictional_heating,
        ),
        MANUFACTURED,
    )
}


SCENES = Registry("scene", "pcverify.scenes", CATALOGUE)


def entries() -> dict[str, Entry]:
    """Every known scene by name (shipped, entry points, registered at run time)."""
    return SCENES.entries()


def register_scene(spec: SceneSpec, origin: str) -> None:
    """Make a scene spec known under its name (plugin module or study file); SceneError on a clash."""
    if not isinstance(spec, SceneSpec):
        raise SceneError(f"{origin}: {spec!r} is not a SceneSpec")
    SCENES.register(spec.name, spec, origin)


def scene_names() -> list[str]:
    return list(entries())


def get_spec(name: str) -> SceneSpec:
    """The spec of the scene called `name` (SceneError if unknown or if a plugin's spec cannot be loaded)."""
    table = entries()
    if not isinstance(name, str) or name not in table:
        raise SceneError(f"scene={name!r} is unknown; allowed: one of {', '.join(table)}")
    entry = table[name]
    if isinstance(entry.target, SceneSpec):
        return entry.target
    module_name, _, attr = str(entry.target).partition(":")
    try:
        spec = getattr(importlib.import_module(module_name), attr)
    except Exception as exc:  # noqa: BLE001 - a plugin's own import-time error, shown as one line
        raise SceneError(f"scene {name!r} ({entry.origin}) is unavailable: {type(exc).__name__}: {exc}") from None
    if not isinstance(spec, SceneSpec):
        raise SceneError(f"scene {name!r} ({entry.origin}): {entry.target} is not a SceneSpec")
    if spec.name != name:
        raise SceneError(f"scene {name!r} ({entry.origin}) is a SceneSpec named {spec.name!r}; allowed: a spec "
                         "registered under its own name")
    return spec


def make_scene(name: str, **params: Any) -> Scene:
    """Build the named scene with parameter overrides; unknown names or bad values raise SceneError, and so
    does a spec that builds a scene under another name (results are labelled by the scene's name: a plugin's
    scene must never be reported as a shipped one)."""
    scene = get_spec(name).make(**params)
    if scene.name != name:
        raise SceneError(f"scene {name!r} ({entries()[name].origin}) built a scene named {scene.name!r}; allowed: "
                         "a scene named as its spec")
    return scene


# -- scenes from data: a study file's [[scene]] tables, built from the shipped building blocks --------------

HEAT_KEYS = ("t_max", "mode", "t_end", "dt", "initial_temperature", "source", "interface", "held")
ELASTIC_KEYS = ("supports", "clamps", "modes")


def _reals(table: dict[str, Any], text: tuple[str, ...] = ()) -> dict[str, Any]:
    """A checked table's numbers as floats (TOML reads 1 as an int), its text fields as they are."""
    return {k: v if k in text else float(v) for k, v in table.items()}


def _held(item: dict[str, Any]) -> Any:
    if "face" in item:
        return FaceTemperature(item["face"], float(item["temperature"]))
    if "point" in item:
        return PointTemperature(tuple(map(float, item["point"])), float(item["temperature"]))
    return PatchTemperature(tuple(map(float, item["patch"])), item.get("radius", math.nan), float(item["temperature"]))


def spec_from_table(table: dict[str, Any], where: str) -> SceneSpec:
    """A SceneSpec from a study file's [[scene]] table (one line per error, naming the field).

    The scene's only parameters are its box dimensions (width, height, length; the table's values are
    the defaults), so that groups can vary them; everything else is fixed by the table (`schema.SCENE`)."""
    check(table, SCENE, where)
    name = table["name"]
    try:
        box = Box(**{"width": BOX.width, "height": BOX.height, "length": BOX.length, **table.get("box", {})})
        material = table.get("material", "aluminium")
        material = MATERIALS[material] if isinstance(material, str) else Material(**{"name": "custom",
                                                                                     **_reals(material, ("name",))})
        heat = any(k in table for k in HEAT_KEYS)
        elastic = any(k in table for k in ELASTIC_KEYS)
        constraints = [_held(item) for item in table.get("held", [])]
        constraints += [FaceSupport(item["face"], float(item.get("displacement", 0.0)))
                        for item in table.get("supports", [])]
        constraints += [FaceClamp(face) for face in table.get("clamps", [])]
        heat_fields = {k: table[k] for k in HEAT_KEYS if k in table and k != "held"}
        if "interface" in heat_fields:
            heat_fields["interface"] = InterfaceFlux(**_reals(heat_fields["interface"], ("axis",)))
        conduction = Conduction(**heat_fields) if heat else None
        elasticity = Elasticity(modes=table.get("modes", 0)) if elastic else None
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{where}: {exc}") from None
    if not heat and not elastic:
        raise SceneError(f"{where}: the scene has no physics; allowed: heat fields ({', '.join(HEAT_KEYS)}) or "
                         f"elasticity fields ({', '.join(ELASTIC_KEYS)})")
    physics = {"conduction"} if heat else set()
    physics |= {"heat-source"} if conduction is not None and conduction.source != 0 else set()
    plane = conduction.interface if conduction is not None else None
    physics |= {"interface-flux"} if plane is not None and plane.flux != 0 else set()
    physics |= {"elasticity"} if elastic else set()
    physics |= {"modes"} if elasticity is not None and elasticity.modes > 0 else set()
    description = table.get("description", f"scene {name} (defined in a study file)")
    dims = tuple(Param(p.name, getattr(box, p.name), p.unit, p.description, low=p.low, high=p.high,
                       low_open=p.low_open) for p in DIMENSIONS)

    def build(p: dict[str, Any]) -> Scene:
        return Scene(name, str(description), box_of(p), material, frozenset(physics), tuple(constraints),
                     conduction=conduction, elasticity=elasticity, params=tuple(sorted(p.items())))

    spec = SceneSpec(name, str(description), dims, build)
    spec.make()  # the scene at its defaults is valid now, not when a cell runs
    return spec
