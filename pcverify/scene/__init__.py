"""The scene model: the vocabulary that solvers consume and plugins are written against.

Geometry and resolution, materials, constraints, the scene with its physics parts, scene specs and
parameter specs.  It is the bottom layer: it imports nothing else of the project, and solvers,
references and the harness all import it.
"""

from .constraints import (
    FACES,
    Constraint,
    FaceClamp,
    FaceSupport,
    FaceTemperature,
    PatchTemperature,
    PointTemperature,
    Support,
    TemperatureConstraint,
    point_patch_note,
)
from .contact import Contact
from .geometry import EXTENT_RANGE, Box, Resolution
from .loads import InterfaceFlux, SineSource
from .material import ALUMINIUM, DURALUMIN, MATERIALS, RESPONSES, Material, Response
from .model import MODES, PHYSICS, Conduction, Elasticity, Scene
from .params import Param, SceneError, is_real, resolve_params, shown
from .spec import Reference, Scalar, SceneSpec

__all__ = [
    "ALUMINIUM", "DURALUMIN", "EXTENT_RANGE", "FACES", "MATERIALS", "MODES", "PHYSICS", "RESPONSES", "Box",
    "Conduction", "Constraint", "Contact", "Elasticity", "FaceClamp", "FaceSupport", "FaceTemperature",
    "InterfaceFlux", "Material", "Param",
    "PatchTemperature", "PointTemperature", "Reference", "Resolution", "Response", "Scalar", "Scene", "SceneError",
    "SceneSpec", "SineSource", "Support",
    "TemperatureConstraint", "is_real", "point_patch_note", "resolve_params", "shown",
]
