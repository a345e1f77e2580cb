"""Bounded work: what one cell may cost before the harness refuses to start it without --allow-large.

A solver that offers `estimate(scene, resolution, **params)` says, before it starts, how many unknowns and
time steps a solve takes and how much memory it needs.  A cell beyond MAX_WORK unknown-steps (about ten
minutes of one core at ~5 ns per unknown-step) or beyond half of this machine's memory is refused in one
line that names the resolution, the estimate and the limit.
"""

from __future__ import annotations

import os
from typing import Any

from pcverify.scene import Resolution, Scene, SceneError
from pcverify.solvers.protocol import Solver

MAX_WORK = 1e11  # unknowns x time steps of one cell
MEMORY_SHARE = 0.5  # of this machine's physical memory


def physical_memory() -> int:
    """This machine's physical memory in bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_work(solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any],
               allow_large: bool) -> None:
    """SceneError if the solver's estimate of this solve is beyond the limits (unless `allow_large`)."""
    estimate = getattr(solver, "estimate", None)  # optional part of the solver protocol
    if estimate is None or allow_large:
        return
    work = estimate(scene, resolution, **params)
    where = f"{solver.name} on {scene.name} at n={resolution.n} refine={resolution.refine}"
    memory = MEMORY_SHARE * physical_memory()
    if work.bytes > memory:
        raise SceneError(f"{where} needs about {work.bytes / 2**30:.3g} GiB ({work.unknowns:.3g} unknowns); "
                         f"allowed: at most {memory / 2**30:.3g} GiB (half of this machine's memory) without "
                         "--allow-large")
    if work.unknowns * work.steps > MAX_WORK:
        raise SceneError(f"{where} is {work.unknowns:.3g} unknowns x {work.steps:.3g} time steps = "
                         f"{work.unknowns * work.steps:.3g} unknown-steps; allowed: at most {MAX_WORK:.0e} without "
                         "--allow-large")
