"""What a continuum solve costs, known before it starts: grid nodes, time steps and memory.

Memory per unknown, measured as peak resident set minus the ~260 MB of a bare `pcverify run` process,
rounded up: scikit-fem heat 1.7 kB per node and FiPy 1.9 kB per cell at 87 451 nodes (n = 4, refine 10);
scikit-fem elasticity 12 kB per degree of freedom with Q2 at 136 875 (n = 4, refine 4; SuperLU fill-in).
"""

from __future__ import annotations

import math

from pcverify.scene import Conduction, Resolution, Scene, SceneError
from pcverify.solvers.protocol import WorkEstimate

HEAT_BYTES_PER_NODE = 2_500
ELASTIC_BYTES_PER_DOF = 12_000


def grid_nodes(scene: Scene, resolution: Resolution) -> int:
    """Nodes of the lattice grid of `resolution` (the lattice of n refined `refine` times)."""
    return math.prod((s - 1) * resolution.refine + 1 for s in scene.box.lattice_shape(resolution.n))


def transient_steps(heat: Conduction, max_steps: int) -> int:
    """Time steps of a transient, round(t_end / dt) (0 when steady); SceneError unless dt divides t_end
    (to 1e-9) and the count is at most `max_steps`."""
    if heat.mode != "transient":
        return 0
    steps = round(heat.t_end / heat.dt)
    if steps < 1 or abs(steps * heat.dt - heat.t_end) > 1e-9 * heat.t_end:
        raise SceneError(f"dt={heat.dt!r} is out of range; allowed: t_end/dt must be an integer (t_end="
                         f"{heat.t_end:g} s)")
    if steps > max_steps:
        raise SceneError(f"t_end / dt = {heat.t_end:g} s / {heat.dt:.3g} s = {steps:.3g} steps is out of range; "
                         f"allowed: at most max_steps={max_steps}; raise dt, or raise max_steps")
    return int(steps)


def heat_estimate(scene: Scene, resolution: Resolution) -> WorkEstimate:
    """Unknowns, steps and memory of a heat solve on the lattice grid."""
    nodes = grid_nodes(scene, resolution)
    heat = scene.conduction
    steps = max(1, round(heat.t_end / heat.dt)) if heat.mode == "transient" else 1
    return WorkEstimate(unknowns=nodes, steps=int(steps), bytes=HEAT_BYTES_PER_NODE * nodes)
