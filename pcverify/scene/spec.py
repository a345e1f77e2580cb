"""A scene specification: a named, parameterised recipe for a scene, with what it is checked against.

A scene family (heat, elastic, contact in `pcverify.references`, or a plugin's own module) declares its
scenes as SceneSpecs that carry their `Reference` (exact values at sample points, expected summary scalars,
a reference curve for the history figure) and the `Scalar`s of its contract: the summary quantities a solver
of the family reports, with their units and sign conventions.  The harness asks a spec for these and names no
scene.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .model import Scene
from .params import Param, resolve_params


@dataclass(frozen=True)
class Scalar:
    """A summary scalar a scene family defines: the name a solver reports it under, its unit, and what it
    is (with its sign convention); `sign(scene)`, where given, is the sign (+1 or -1, 0: either) every
    non-zero value must have on that scene, which the harness checks on every solution."""

    name: str
    unit: str
    description: str
    sign: Callable[[Scene], int] | None = None


@dataclass(frozen=True)
class Reference:
    """What a scene's solutions are compared with; every part is optional and may answer None for a scene of
    the spec it does not cover (then the harness compares nothing for it).

    - `field(scene, points)`: the exact sampled quantity (as the solution reports it, e.g. T / t_max) at
      `points` (shape (k, 3)), or None;
    - `scalars(scene, summary)`: {name: expected value} of summary scalars; `summary` is the cell's own
      summary (a reference may be conditional on a measured value, e.g. the kinetic half of a stick-slip
      cycle given the measured breakaway force), {} when asked before any solve;
    - `history(scene, t)` or `history(scene, t, summary)`: (values, label) of the reference curve drawn under
      the history figure at times t, or None; a curve of three arguments gets the cell's summary, so it may be
      drawn for the run's own lattice (the stick-slip block on the slider's contacts at its spacing);
    - `kind`: what the numbers stand on (analytic, theory, paper)."""

    field: Callable[[Scene, np.ndarray], np.ndarray | None] | None = None
    scalars: Callable[[Scene, dict[str, Any]], dict[str, float]] | None = None
    history: Callable[..., tuple[np.ndarray, str] | None] | None = None
    kind: str = "analytic"


@dataclass(frozen=True)
class SceneSpec:
    """A named scene: one-line description, its parameters (default, unit, range), the builder that turns
    their effective values into a `Scene`, its reference (None: compared with continuum solvers only) and the
    summary scalars its family defines."""

    name: str
    description: str
    parameters: tuple[Param, ...]
    build: Callable[[dict[str, Any]], Scene]
    reference: Reference | None = None
    scalars: tuple[Scalar, ...] = ()

    def make(self, **given: Any) -> Scene:
        """The scene for parameter overrides `given`; unknown names or bad values raise SceneError."""
        values = resolve_params(self.parameters, given, f"scene {self.name!r}")
        return self.build(values)
