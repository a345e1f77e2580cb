"""A cell task that hands its solver one perturbed input (`pcverify sensitivity`).

Its own module because a cell's cache key holds the fingerprint of its task's module: the rules that judge
what moved (harness/run/sensitivity.py) can change without recomputing the perturbed cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from pcverify.fingerprint import module_fingerprint
from pcverify.harness.study.tasks import CellTask
from pcverify.scene import Resolution, Scene
from pcverify.solvers.protocol import Solver


@dataclass(frozen=True)
class Perturbed:
    """A cell task that hands the solver a perturbed input (`scene`: the perturbed scene, or `param`, `value`: a
    solver parameter) and runs the cell's own task with it; `label` names the perturbation in the cache key."""

    inner: CellTask
    label: str
    scene: Scene | None = None
    param: str = ""
    value: float = math.nan
    original: float = math.nan  # the parameter's value in the cell

    @property
    def name(self) -> str:
        return f"{self.inner.name} [{self.label}; {module_fingerprint(type(self.inner).__module__)}]"

    def _params(self, params: dict[str, Any]) -> dict[str, Any]:
        return params | ({self.param: self.value} if self.param else {})

    def supports(self, solver: Solver, scene: Scene) -> tuple[bool, str]:
        return self.inner.supports(solver, self.scene or scene)

    def check(self, solver: Solver, params: dict[str, Any]) -> dict[str, Any]:
        return self.inner.check(solver, self._params(params))

    def run(self, solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> dict[str, Any]:
        """The inner task's result; a summary scalar that echoes the perturbed parameter (a row a claim selects
        by it) reports the cell's value, so the claim's cases stay the same rows."""
        out = self.inner.run(solver, self.scene or scene, resolution, self._params(params))
        for part in ("summary", "params"):
            if self.param and self.param in (out.get(part) or {}):
                out[part] = out[part] | {self.param: self.original}
        return out
