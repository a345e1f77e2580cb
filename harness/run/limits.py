"""Bounded work: what one cell may cost before the harness refuses to start it without --allow-large, and
how long it may run before it is stopped.

A solver's `estimate(scene, resolution, **params)` says how many unknowns and time steps a solve takes and how
much memory it needs.  A cell beyond MAX_WORK unknown-steps (about ten minutes of one core) or beyond half of
this machine's memory is refused in one line; an estimate that raises or answers something other than a
WorkEstimate is an `EstimateError` naming the solver.  Whatever the estimate said, a computed cell is killed
after its time limit (DEFAULT_TIME_LIMIT: six times what MAX_WORK allows, room for a slow machine and for
solvers without an estimate), and a mutant's whole run after DEFAULT_MUTANT_TIME_LIMIT.
"""

from __future__ import annotations

import copy
import math
import os
from typing import Any

from pcverify.scene import Resolution, Scene, SceneError, shown
from pcverify.solvers.protocol import Solver

MAX_WORK = 1e11  # unknowns x time steps of one cell
MEMORY_SHARE = 0.5  # of this machine's physical memory
DEFAULT_TIME_LIMIT = 3600.0  # seconds one computed cell may run
# the longest --time-limit: 24 days; the wait on a worker is a poll() in milliseconds, whose longest timeout,
# 2^31 - 1 ms, is 24.86 days (a longer one raises OverflowError)
MAX_TIME_LIMIT = 24 * 24 * 3600.0
DEFAULT_MUTANT_TIME_LIMIT = 7200.0  # seconds a mutant's whole run may take (`pcverify mutate`)


class EstimateError(SceneError):
    """A solver's `estimate` that raised or did not return a WorkEstimate: its cell cannot be checked
    against the limits (one line naming the solver)."""


def physical_memory() -> int:
    """This machine's physical memory in bytes."""
    return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")


def check_work(solver: Solver, scene: Scene, resolution: Resolution, params: dict[str, Any],
               allow_large: bool, label: str | None = None) -> None:
    """SceneError if the solver's estimate of this solve is beyond the limits (unless `allow_large`);
    EstimateError if the estimate raises or is not a WorkEstimate.  `label`: the solver's name as the user
    gave it (default its `name`); the estimate sees a copy of the scene."""
    who = label or solver.name
    if allow_large:
        return
    try:
        estimate = getattr(solver, "estimate", None)  # optional part of the solver protocol
        if estimate is None:
            return
        work = estimate(copy.deepcopy(scene), resolution, **params)
        unknowns, steps, size = (_count(getattr(work, k, None)) for k in ("unknowns", "steps", "bytes"))
    except (SceneError, KeyboardInterrupt):
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's estimate: one line, never a traceback
        try:
            text = " ".join(str(exc).split())
        except Exception:  # noqa: BLE001 - an exception whose message cannot be shown
            text = ""
        raise EstimateError(f"solver {who!r}: estimate(scene, resolution) raised {type(exc).__name__}"
                            f"{': ' + text if text else ''}; allowed: a WorkEstimate (--allow-large skips the "
                            "estimate)") from None
    if None in (unknowns, steps, size):
        raise EstimateError(f"solver {who!r}: estimate(scene, resolution) returned {shown(work)}; allowed: a "
                            "WorkEstimate of unknowns, steps and bytes >= 0 (--allow-large skips the estimate)")
    where = f"{who} on {scene.name} at n={resolution.n} refine={resolution.refine}"
    memory = MEMORY_SHARE * physical_memory()
    if size > memory:
        raise SceneError(f"{where} needs about {size / 2**30:.3g} GiB ({unknowns:.3g} unknowns); "
                         f"allowed: at most {memory / 2**30:.3g} GiB (half of this machine's memory) without "
                         "--allow-large")
    if unknowns * steps > MAX_WORK:
        raise SceneError(f"{where} is {unknowns:.3g} unknowns x {steps:.3g} time steps = "
                         f"{unknowns * steps:.3g} unknown-steps; allowed: at most {MAX_WORK:.0e} without "
                         "--allow-large")


def _count(value: Any) -> float | None:
    """A finite number >= 0 of an estimate, or None."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) and not hasattr(value, "__float__"):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        return None
    return number if math.isfinite(number) and number >= 0 else None
