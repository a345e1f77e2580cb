"""pcverify: verify particle methods against continuum solvers and analytic solutions.

This package is the public API a solver or scene plugin is written against: the scene model
(`Scene` and its parts, `Param`, `Resolution`), the `Solver` protocol, `Solution` and `skipped`.
Everything else (`pcverify.harness`, `pcverify.solvers`, `pcverify.references`) is the product's own
and may change between versions.
"""

from __future__ import annotations

from importlib import metadata

from pcverify.scene import Param, Resolution, Scene, SceneError
from pcverify.solvers.protocol import Solution, Solver, skipped

try:
    __version__ = metadata.version("pcverify")
except metadata.PackageNotFoundError:  # a source tree that is not installed
    __version__ = "0+unknown"

__all__ = ["Param", "Resolution", "Scene", "SceneError", "Solution", "Solver", "skipped", "__version__"]
