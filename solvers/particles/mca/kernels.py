"""The MCA kernel family: the time-stepping kernels by name, all with one signature.

A kernel is `kernel(state, params, nsteps)`: `state` a typing.NamedTuple of arrays (advanced in place),
`params` a typing.NamedTuple of scalars, `nsteps` the number of steps.  "mechanics" is velocity Verlet of
the automata (kernel.py: pair and many-body forces, optional rotations, response functions, loads);
"heat" is forward Euler of the automata's temperatures (heat.py).  `timed` runs a kernel and returns the
seconds of its steps alone: a call of no steps first loads numba's dispatcher and cache, which a fresh
process would otherwise count as kernel time.
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
