"""pcverify: verify particle methods against continuum solvers and analytic solutions.

This package is the public API a solver or scene plugin is written against (API_VERSION; what is
stable is listed in docs/plugins.md, "What is stable"):

- the scene model: `Scene` and its parts (`Box`, `Material`, `Conduction` with a volumetric
  `source`, a `source_field` of `SineSource` terms and an `InterfaceFlux`, `Elasticity`, the constraints
  `FaceTemperature`, `PointTemperature`, `PatchTemperature`, `FaceSupport`, `FaceClamp`), `Resolution`,
  `Param` and `SceneError`, and
  `SceneSpec` (a named, parameterised scene with its `Reference` and the `Scalar`s of its family's contract);
- the solver contract: the `Solver` protocol (name, kind in KINDS, parameters, supports, solve),
  `Solution`, `skipped`, `effective_params`, and the optional stability probe (`StabilityProbe`,
  `ProbeSetup`, `ProbeRun`);
- for a solver that computes a bar's modes: `classify_modes` (the kind of each mode by its mirror parities, the
  classifier the shipped solvers use), `lowest_of_each_kind` (the `f_<kind>_hz` summary keys) and `MODE_KINDS`;
- for a plugin's unit tests: `make_scene(name, **params)`, any scene the catalogue knows (shipped or a plugin's).
  These four are loaded on first use (`import pcverify` stays light).

Plugins are found through the entry point groups `pcverify.solvers` and `pcverify.scenes`, a study
file's `plugins = [...]`, or `--solver module:Class`.  Everything else (`pcverify.harness`,
`pcverify.solvers`, `pcverify.references`) is the product's own and may change between versions.

Importing pcverify guards numba's on-disk cache (`numba_guard`): a function compiled with cache=True
afterwards is recompiled when any module it reaches by import changes, not only its own file.
"""

from __future__ import annotations

import importlib
from importlib import metadata

from pcverify.numba_guard import guard_numba_cache

guard_numba_cache()  # first: before any module defines a numba function with cache=True

from pcverify.scene import (  # noqa: E402
    ALUMINIUM,
    DURALUMIN,
    FACES,
    PHYSICS,
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
    Resolution,
    Response,
    Scalar,
    Scene,
    SceneError,
    SceneSpec,
    SineSource,
)
from pcverify.solvers.protocol import (  # noqa: E402
    KINDS,
    STATUSES,
    ProbeRun,
    ProbeSetup,
    Solution,
    Solver,
    StabilityProbe,
    effective_params,
    skipped,
)

API_VERSION = "1"  # raised when a name of the public API changes incompatibly

# public names loaded on first use: (module, attribute)
_LAZY = {"classify_modes": ("pcverify.solvers.modes", "classify"),
         "lowest_of_each_kind": ("pcverify.solvers.modes", "lowest_of_each_kind"),
         "MODE_KINDS": ("pcverify.solvers.modes", "KINDS"),
         "make_scene": ("pcverify.harness.study.catalogue", "make_scene")}


def __getattr__(name: str) -> object:
    """The lazily loaded public names (_LAZY)."""
    if name in _LAZY:
        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'pcverify' has no attribute {name!r}")

try:
    __version__ = metadata.version("pcverify")
except metadata.PackageNotFoundError:  # a source tree that is not installed
    __version__ = "0+unknown"

__all__ = [
    "ALUMINIUM", "API_VERSION", "DURALUMIN", "FACES", "KINDS", "PHYSICS", "STATUSES", "Box", "Conduction",
    "Elasticity", "FaceClamp", "FaceSupport", "FaceTemperature", "InterfaceFlux", "Material", "Param",
    "PatchTemperature", "PointTemperature", "ProbeRun", "ProbeSetup", "Reference", "Resolution", "Response", "Scalar",
    "Scene",
    "SceneError", "SceneSpec", "SineSource", "Solution", "Solver", "StabilityProbe", "__version__", "effective_params",
    "skipped", "classify_modes", "lowest_of_each_kind", "MODE_KINDS", "make_scene",
]
