"""The catalogue of named scenes: the shipped ones, those of installed plugins and those a study defines.

A scene is a `SceneSpec`: parameters (default, range, unit), the builder that turns their values into a
`Scene`, its reference and its family's scalar contract.  Shipped scenes come from their families
(`pcverify.references`); plugin distributions add theirs through the `pcverify.scenes` entry point group (name
-> "module:attribute", the attribute a SceneSpec); plugin modules and study files register theirs at run time.
Two sources that give the same name are an error that names both.
"""

from __future__ import annotations

import importlib
import math
from typing import Any

from pcverify import references
from pcverify.harness.study.schema import SCENE, check
from pcverify.references.heat import FIELD as SLAB
from pcverify.references.heat import SCALARS as HEAT_SCALARS
from pcverify.references.shared import DIMENSIONS, box_of
from pcverify.scene import (
    MATERIALS,
    Box,
    Conduction,
    Elasticity,
    FaceClamp,
    FaceSupport,
    FaceTemperature,
    InterfaceFlux,
    Material,
    Param,
    PatchTemperature,
    PointTemperature,
    Reference,
    Scene,
    SceneError,
    SceneSpec,
)
from pcverify.solvers.registry import Entry, Registry

CATALOGUE: dict[str, SceneSpec] = {spec.name: spec for spec in references.SCENES}
SCENES = Registry("scene", "pcverify.scenes", CATALOGUE)


def entries() -> dict[str, Entry]:
    """Every known scene by name (shipped, entry points, registered at run time)."""
    return SCENES.entries()


def register_scene(spec: SceneSpec, origin: str) -> None:
    """Make a scene spec known under its name (plugin module or study file); SceneError on a clash."""
    if not isinstance(spec, SceneSpec):
        raise SceneError(f"{origin}: {spec!r} is not a SceneSpec")
    SCENES.register(spec.name, spec, origin)


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
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's own import-time error (SystemExit too), one line
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


def reference_of(name: str) -> Reference | None:
    """The reference of the scene `name`; one this process does not know (a study file's scene, in a worker that
    did not load the study file) gets what every study-file scene gets, the heat family's slab."""
    return get_spec(name).reference if name in entries() else SLAB


def spec_modules(name: str) -> tuple[str, ...]:
    """The modules defining the scene's builder and reference (its compared results depend on them)."""
    spec = get_spec(name)
    parts = (spec.build, *(spec.reference or Reference()).__dict__.values())
    return tuple(sorted({getattr(f, "__module__", None) or type(f).__module__ for f in parts if callable(f)}))


# -- scenes from data: a study file's [[scene]] tables, built from the shipped building blocks, compared with the
# heat family's slab (where the scene reduces to one) ---------------------------------------------------------

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
    doc = check(table, SCENE, where)  # with the schema's defaults; which physics it has is what `table` gives
    name = doc["name"]
    try:
        box = Box(**doc.get("box", {}))
        material = doc["material"]
        material = MATERIALS[material] if isinstance(material, str) else Material(**{"name": "custom",
                                                                                     **_reals(material, ("name",))})
        heat = any(k in table for k in HEAT_KEYS)
        elastic = any(k in table for k in ELASTIC_KEYS)
        constraints = [_held(item) for item in doc.get("held", [])]
        constraints += [FaceSupport(item["face"], float(item["displacement"])) for item in doc.get("supports", [])]
        constraints += [FaceClamp(face) for face in doc.get("clamps", [])]
        heat_fields = {k: doc[k] for k in HEAT_KEYS if k in table and k != "held"}
        if "interface" in heat_fields:
            heat_fields["interface"] = InterfaceFlux(**_reals(heat_fields["interface"], ("axis",)))
        conduction = Conduction(**heat_fields) if heat else None
        elasticity = Elasticity(modes=doc["modes"]) if elastic else None
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
    description = doc.get("description", f"scene {name} (defined in a study file)")
    dims = tuple(Param(p.name, getattr(box, p.name), p.unit, p.description, low=p.low, high=p.high,
                       low_open=p.low_open) for p in DIMENSIONS)

    def build(p: dict[str, Any]) -> Scene:
        return Scene(name, str(description), box_of(p), material, frozenset(physics), tuple(constraints),
                     conduction=conduction, elasticity=elasticity, params=tuple(sorted(p.items())))

    spec = SceneSpec(name, str(description), dims, build, SLAB, HEAT_SCALARS)
    spec.make()  # the scene at its defaults is valid now, not when a cell runs
    return spec
