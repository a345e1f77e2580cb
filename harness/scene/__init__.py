"""The scene model: the vocabulary that solvers consume.

Geometry and resolution, materials, constraints, the scene with its physics parts, and parameter
specs.  This package imports nothing else of the project, so solvers may import it (and only it of
the harness); plugins reach it through the public API, `pcverify`.
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
)
from .geometry import Box, Resolution
from .material import ALUMINIUM, DURALUMIN, MATERIALS, RESPONSES, Material, Response
from .model import MODES, PHYSICS, Conduction, Elasticity, Scene
from .params import Param, SceneError, resolve_params, shown

__all__ = [
    "ALUMINIUM", "DURALUMIN", "FACES", "MATERIALS", "MODES", "PHYSICS", "RESPONSES", "Box", "Conduction", "Constraint",
    "Elasticity", "FaceClamp", "FaceSupport", "FaceTemperature", "Material", "Param", "PatchTemperature",
    "PointTemperature", "Resolution", "Response", "Scene", "SceneError", "Support", "TemperatureConstraint",
    "resolve_params", "shown",
]
