"""Heat transfer between linked automata: q_ij = lambda (T_j - T_i) S_ij / r_ij (docs/physics.md,
"The movable cellular automaton (MCA) model").

Each automaton carries a temperature and the heat capacity C_i = rho c Omega_i of its cell; on the bar
lattice this is the cell-centred finite-volume scheme on the node-centred (Voronoi) cells, second order in a.
Transient: explicit (forward Euler) with the stable step dt <= min_i C_i / sum_j G_ij (G_ij = lambda S/r,
the Gershgorin bound: forward Euler is stable for dt <= 2 / rho(C^-1 L) and rho <= 2 max_i sum_j G_ij / C_i),
times `cfl` <= 1; the step count is rounded up so that the last step lands on t_end.
Steady: the same operator's steady state, solved directly (sparse LU) instead of stepping to it.
Held automata (temperature constraints) keep their value from t = 0+.  Sources (`sources`): the volumetric
source s Omega_i (a varying one s(x_i) Omega_i) and an interface flux shared between the node planes around its
plane; the frictional heating of contact scenes brings its own per-automaton power.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numba import njit
from scipy.sparse.linalg import spsolve

from pcverify.scene import (
    FaceClamp,
    FaceSupport,
    FaceTemperature,
    PatchTemperature,
    PointTemperature,
    Scene,
    SceneError,
)

from .automata import Automata


def conductances(aut: Automata, conductivity: float) -> np.ndarray:
    """G_p = lambda S_p / r0_p of every linked pair."""
    return conductivity * aut.area / aut.r0


def stable_step(aut: Automata, cap: np.ndarray, g: np.ndarray, free: np.ndarray) -> float:
    """Largest forward-Euler step by the Gershgorin bound over the free automata: min C_i / sum_j G_ij."""
    rowsum = np.bincount(aut.pairs[:, 0], g, aut.size) + np.bincount(aut.pairs[:, 1], g, aut.size)
    return float(np.min(cap[free] / rowsum[free]))


class HeatState(NamedTuple):
    """Arrays of the explicit heat kernel: temperatures (advanced), heat capacities C_i, the conducting pairs
    and their conductances G_p, the held mask (1 = held), a scratch array for the net heat flows, and the
    heat sources P_i (W, constant; None: none)."""

    temp: np.ndarray
    cap: np.ndarray
    pi: np.ndarray
    pj: np.ndarray
    g: np.ndarray
    held: np.ndarray
    flow: np.ndarray
    power: np.ndarray | None = None


class HeatParams(NamedTuple):
    """Scalars of the explicit heat kernel: the time step (s)."""

    dt: float


def heat_state(aut: Automata, temp: np.ndarray, cap: np.ndarray, g: np.ndarray, held: np.ndarray,
               power: np.ndarray | None = None) -> HeatState:
    """The kernel state of the automata's pairs (a copy of temp is advanced); power: sources P_i (W) or None."""
    return HeatState(temp=np.asarray(temp, dtype=float).copy(), cap=cap, pi=aut.pairs[:, 0].copy(),
                     pj=aut.pairs[:, 1].copy(), g=g, held=np.asarray(held, dtype=np.int64), flow=np.zeros(aut.size),
                     power=None if power is None else np.asarray(power, dtype=float))


@njit(cache=True)
def explicit_run(st, par, nsteps):
    """Forward Euler: T_i += dt / C_i (sum_j G_ij (T_j - T_i) + P_i) for the free automata, `nsteps` times."""
    _explicit(st, par, st.power, nsteps)


@njit(cache=True)
def _explicit(st, par, power, nsteps):
    temp, cap, pi, pj, g, held, flow = st.temp, st.cap, st.pi, st.pj, st.g, st.held, st.flow
    n = temp.shape[0]
    dt = par.dt
    for _ in range(nsteps):
        for i in range(n):
            flow[i] = 0.0
        for p in range(pi.shape[0]):
            q = g[p] * (temp[pj[p]] - temp[pi[p]])
            flow[pi[p]] += q
            flow[pj[p]] -= q
        if power is not None:
            for i in range(n):
                flow[i] += power[i]
        for i in range(n):
            if held[i] == 0:
                temp[i] += dt * flow[i] / cap[i]


def explicit_system(aut: Automata, conductivity: float, rho_c: float, held: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """(heat capacities C_i, conductances G_p, Gershgorin step) of the explicit scheme."""
    cap = rho_c * aut.volume
    g = conductances(aut, conductivity)
    return cap, g, stable_step(aut, cap, g, held == 0)


def laplacian(aut: Automata, g: np.ndarray) -> sp.csr_matrix:
    """L with (L T)_i = sum_j G_ij (T_i - T_j) over the linked pairs."""
    pi, pj = aut.pairs[:, 0], aut.pairs[:, 1]
    n = aut.size
    return sp.coo_matrix((np.concatenate([g, g, -g, -g]), (np.concatenate([pi, pj, pi, pj]),
                                                           np.concatenate([pi, pj, pj, pi]))), shape=(n, n)).tocsr()


def transient(aut: Automata, conductivity: float, rho_c: float, temp0: np.ndarray, held: np.ndarray, t_end: float,
              cfl: float, power: np.ndarray | None = None) -> tuple[HeatState, HeatParams, int]:
    """The explicit run from temp0 to t_end (held automata keep theirs; sources P_i in W): (state, params,
    steps); the step is cfl times the Gershgorin step, shortened so that a whole number of steps lands on
    t_end."""
    cap, g, dt_g = explicit_system(aut, conductivity, rho_c, held)
    dt_max = cfl * dt_g
    steps = max(1, math.ceil(t_end / dt_max * (1 - 1e-12)))
    return heat_state(aut, temp0, cap, g, held, power), HeatParams(t_end / steps), steps


def steady(aut: Automata, conductivity: float, values: np.ndarray, held: np.ndarray,
           power: np.ndarray | None = None) -> np.ndarray:
    """Steady state of the same scheme: sum_j G_ij (T_j - T_i) + P_i = 0 on the free automata."""
    lap = laplacian(aut, conductances(aut, conductivity))
    n = aut.size
    free = np.flatnonzero(held == 0)
    fixed = np.flatnonzero(held != 0)
    temp = np.zeros(n)
    temp[fixed] = values[fixed]
    rhs = -(lap[free][:, fixed] @ temp[fixed])
    if power is not None:
        rhs = rhs + power[free]
    temp[free] = spsolve(lap[free][:, free].tocsc(), rhs)
    return temp


def sources(scene: Scene, aut: Automata) -> np.ndarray | None:
    """Heat sources P_i (W) of the scene's Conduction part on the automata, or None: the volumetric source
    s Omega_i (a source field: s(x_i) Omega_i, x_i the automaton's lattice position), and the interface flux q
    shared between the two node planes around its plane by hat weights max(0, 1 - |x_i - x_p| / a) times the
    cell's face A_i normal to the axis (all of it on a node plane; half to each side at mid-plane, which is the
    finite-volume split of a source on a cell face)."""
    heat = scene.conduction
    plane = heat.interface if heat.interface is not None and heat.interface.flux != 0.0 else None
    if heat.source == 0.0 and plane is None and not heat.source_field:
        return None
    power = heat.source_at(aut.positions) * aut.volume if heat.source_field else heat.source * aut.volume
    if plane is not None:
        ax = plane.axis_index
        a = float(aut.spacing[ax])
        hat = np.maximum(0.0, 1.0 - np.abs(aut.positions[:, ax] - plane.position) / a)
        face = np.prod(np.delete(aut.extent, ax, axis=1), axis=1)
        power = power + plane.flux * face * hat
    return power


def held_temperatures(scene: Scene, aut: Automata) -> tuple[np.ndarray, np.ndarray]:
    """Held mask (1 = held) and values (K; free automata: the initial temperature) of the scene's temperature
    constraints on the automata.  A patch smaller than the automata holds the one nearest its centre."""
    held = np.zeros(aut.size, dtype=np.int64)
    values = np.full(aut.size, scene.conduction.initial_temperature, dtype=float)
    for c in scene.constraints:
        if isinstance(c, (FaceSupport, FaceClamp)) and scene.elasticity is not None:
            continue  # a mechanical support of a coupled scene: no heat condition
        if isinstance(c, FaceTemperature):
            idx = aut.on_face(c.face, scene.box.extent)
        elif isinstance(c, PointTemperature):
            idx = aut.node_at(np.asarray(c.point))
        elif isinstance(c, PatchTemperature):
            d = np.linalg.norm(aut.positions - np.asarray(c.centre), axis=1)
            idx = np.flatnonzero(d <= c.radius * (1 + 1e-9))
            if idx.size == 0:
                idx = np.array([int(np.argmin(d))])
        else:
            raise SceneError(f"mca heat: constraint {type(c).__name__} is not a temperature constraint")
        held[idx] = 1
        values[idx] = c.value
    return held, values
