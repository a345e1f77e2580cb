"""What a study cell computes: a cell task takes a solver, a scene, a resolution and parameters and returns
the cell's JSON-ready result.  Every cell runs through one path (`pcverify.harness.run.execution`); the
task is the only thing that differs: a solve (this module) or a stability measurement
(`pcverify.harness.study.stability.StabilityTask`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from pcverify.harness.study.boundary import admitted
from pcverify.harness.study.stability import StabilityTask
from pcverify.scene import Resolution, Scene
from pcverify.solvers.protocol import Solver, effective_params


class CellTask(Protocol):
    """A task: its name (part of the cache key), whether it can run a scene, a check of the parameters
    before anything runs (returning the values that identify the work: part of the cache key), and the
    run."""

    @property
    def name(self) -> str: ...

    def supports(self, solver: Solver, scene: Scene) -> tuple[bool, str]: ...

    def check(self, solver: Solver, params: dict[str, Any]) -> dict[str, Any]: ...

    def run(self, solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> dict[str, Any]: ...


class SupportsAnswerError(TypeError):
    """A `supports` that answered something other than (True or False, a reason text); `answer` is what it
    returned."""

    def __init__(self, answer: Any) -> None:
        super().__init__("supports(scene) must return (True or False, a reason text)")
        self.answer = answer


def ask_supports(task: CellTask, solver: Solver, scene: Scene) -> tuple[bool, str]:
    """(supported, reason) of `task.supports(solver, scene)`: what the solver raises propagates, an answer of
    another form is a SupportsAnswerError.  The one place that says what a valid answer is."""
    answer = task.supports(solver, scene)
    try:
        ok, reason = answer
    except (TypeError, ValueError):
        raise SupportsAnswerError(answer) from None
    if not isinstance(ok, (bool, np.bool_)) or not isinstance(reason, str):
        raise SupportsAnswerError(answer)
    return bool(ok), reason


@dataclass(frozen=True)
class SolveTask:
    """The default task: `solver.solve`, its Solution as a dict once the boundary checks admit it
    (`boundary.Inadmissible` otherwise), with the solver's kind."""

    @property
    def name(self) -> str:
        return "solve"

    def supports(self, solver: Solver, scene: Scene) -> tuple[bool, str]:
        return solver.supports(scene)

    def check(self, solver: Solver, params: dict[str, Any]) -> dict[str, Any]:
        """The solver's effective parameters (SceneError names a bad one)."""
        return effective_params(solver, params)

    def run(self, solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any]) -> dict[str, Any]:
        solution = solver.solve(scene, resolution, **params)
        return admitted(solution, solver, scene, resolution) | {"solver_kind": solver.kind}


SOLVE = SolveTask()
TASKS: dict[str, CellTask] = {t.name: t for t in (SOLVE, StabilityTask("limit"), StabilityTask("map"))}
