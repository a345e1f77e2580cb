"""The MCA kernel family by name, one signature `kernel(state, params, nsteps)` (named tuples of arrays,
advanced in place, and of scalars): "mechanics" (kernel.py) and "heat" (heat.py).  `timed` returns the seconds
of a kernel's steps alone: a call of no steps first loads numba's dispatcher and cache.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from . import heat, kernel

KERNELS: dict[str, Callable[[Any, Any, int], None]] = {
    "mechanics": kernel.advance,
    "heat": heat.explicit_run,
}


def timed(name: str, state: Any, params: Any, nsteps: int) -> float:
    """Run kernel `name` for `nsteps` steps; the seconds spent in the steps (dispatch and cache load excluded)."""
    run = KERNELS[name]
    run(state, params, 0)
    t0 = time.perf_counter()
    run(state, params, int(nsteps))
    return time.perf_counter() - t0
