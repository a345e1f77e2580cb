"""Large-N kernel of the macromolecule model: Verlet list with offset groups, race-free force passes,
prange over particles, K replicas in one kernel.

The same model as the solver's fixed-pair-list kernel (seven-root pair force F(r) plus radial
damping delta * rdot, F > 0 attraction), for lattices up to ~10^6 particles on a few cores:

- pairs come from a `neighbours.NeighbourList` (cell list, skin, rebuilt on demand), not from
  the rest lattice; a pair interacts while r < r_cut.  With r_cut between 2a and sqrt(5) a
  (default 2.1 a) the interacting set of a vibrating lattice is exactly the fixed list's
  (all pairs with r0 <= 2a: the force vanishes at 2a, the damping acts out to r_cut, as in
  LAMMPS' dpd/ext cutoff);
- the list's offset groups (the 16 lattice offsets o = j - i, chosen from the rest lattice) are
  evaluated as contiguous loops over all slots (i, i + o), zeroed beyond r_cut: structure of
  arrays, unsigned indices, a branch-free pair term (`force.force_tree`: the root-factor product tree
  and clamped STEP), so LLVM vectorises them (zmm on AVX-512).  Residual pairs (other offsets: lattice
  defects, particles out of lattice order) are summed per row (gather) after the groups;
- two group passes, both free of write races and bit-identical for any number of threads:
  "slabs" (default): each pair evaluated once and its term added to both particles; particles are
  cut into index blocks at least as wide as the largest offset, so a block writes only into itself
  and the next block; blocks of one colour (even, then odd) run in parallel.  "gather": each pair
  evaluated twice, particle i writes f[i] only.  Block width, tiles and summation order depend on
  N and the offsets only, never on the thread count;
- replicas (ensemble.py): state (3, N, K), replica innermost, so the flat index i * K + k is a
  lattice with offsets o * K and the same loops run over all replicas at once; every replica does
  the operations of its single run (K = 1) in the same order: bit-identical to it;
- time stepping is velocity Verlet (LAMMPS fix nve): half kick, drift, forces, half kick.  The
  damping in F_{n+1} uses v_{n+1/2}, the velocities at force time (LAMMPS' dpd does the same;
  it is the half-step predictor of the solver's kernels, see kernel_reference.py).  The closing half kick
  of a step, the next half kick and drift and the list's displacement check are one contiguous
  pass over all slots (every slot treated as free); held particles are corrected after it;
- fixes (`codes`): FREE, FROZEN (held at rest), PRESCRIBED (x = x_rest + amp sin(omega t + phase));
- memory: state x, v, f (72 B per particle and replica), rest positions, drive amplitudes and
  phases, kinds (57 B), the list's reference positions and residual row offsets (32 B); the
  groups cost nothing per particle.

The kernels take structures numba accepts (typed named tuples): the state (`SlotState`), the fixes
(`DriveArrays`), one parameter set per replica (`ReplicaParams`: damping, drive frequency and
amplitude scale, so that K parameter sets are integrated in one call), the list (`ListArrays`), the
pair force (`PairParams`) and the steps (`StepParams`).  The envelope (a/r)^2 and any other exponent
have a compiled function each (`advance_p2`, `advance_any`, `forces_p2`, `forces_any`), compiled
only when used.

Work counter: a pair-step is one interacting pair (i < j, r < r_cut) advanced one step (the
gather evaluates each twice, the slab pass once; group slots beyond r_cut are work not counted).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import llvmlite.binding as llvm
import numpy as np
from numba import njit, prange

from pcverify.scene import Box, SceneError

from ..codes import DONE, EXPIRED, FREE, FROZEN, KIND_NAMES, PRESCRIBED
from ..force import C_A, C_P, C_PINT, C_ROOTS, C_X0, C_X1, SevenRoot, energy_x, force_tree, shell_stiffness
from .neighbours import NeighbourList, build_neighbours, stencil_offsets

KINDS = (FREE, FROZEN, PRESCRIBED)  # the fixes this kernel takes
DEFAULT_R_CUT = 2.1  # in units of a: above the 2a shell, below the sqrt(5) a shell
DEFAULT_SKIN = 0.1  # in units of a: list radius 2.2 a < sqrt(5) a: at rest exactly the 16 lattice offsets
FORCE_PASSES = ("slabs", "gather")
TILE = 512  # particles per tile of the group loops: the tile's data and slot terms stay in L1/L2

# As in kernel_fast.py: the group loop reads 6 arrays in two ranges and writes 3; LLVM's default limit on
# runtime alias checks would keep it scalar.  Only changes which loops vectorise, never a result (no
# fastmath, no floating-point reductions in the vectorised loops).
llvm.set_option("", "-vectorize-memory-check-threshold=4096")


class PairParams(NamedTuple):
    """Scalars of the pair term: the seven roots (units of a), A, STEP start, 1/STEP width, 1/a, a, the
    envelope exponent p and r_cut^2."""

    r0: float
    r1: float
    r2: float
    r3: float
    r4: float
    r5: float
    r6: float
    amp_a: float
    step_lo: float
    inv_w: float
    inv_a: float
    a: float
    p: float
    rc2: float


class SlotState(NamedTuple):
    """Positions, velocities and forces (3, N * K), replica innermost (flat index i * K + k); hot (N * K)
    accumulates KE dt (empty: no hotness)."""

    xs: np.ndarray
    vs: np.ndarray
    fs: np.ndarray
    hot: np.ndarray


class DriveArrays(NamedTuple):
    """Fixes shared by the replicas: rest positions (N, 3), kinds (N, int8: FREE, FROZEN, PRESCRIBED), the
    held particles' indices, drive amplitudes (N, 3) and phases (N), and the indices of the FREE particles
    in a 0 K viscous bath (an absorbing face; its rate per replica is ReplicaParams.gamma)."""

    x_rest: np.ndarray
    kind: np.ndarray
    held: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    bath: np.ndarray


class ReplicaParams(NamedTuple):
    """One parameter set per replica (K each): drive amplitude scale, drive angular frequency (rad/s),
    radial damping delta (N s/m), force scale A (N), envelope exponent p and the absorbing bath's rate
    gamma (1/s).  A and p replace PairParams' amp_a and p in the force passes."""

    scale: np.ndarray
    omega: np.ndarray
    delta: np.ndarray
    amp_a: np.ndarray
    p: np.ndarray
    gamma: np.ndarray


class ListArrays(NamedTuple):
    """The neighbour list as the kernels read it: offset groups, slab block width (0: gather pass),
    residual CSR rows (start, index), the reference positions (N * K, 3) and half the skin."""

    offsets: np.ndarray
    block: int
    start: np.ndarray
    index: np.ndarray
    x_ref: np.ndarray
    half_skin: float


class StepParams(NamedTuple):
    """Particle mass, time step, the step count at the call's start, steps to do, and whether the call
    resumes a step whose drift is done (after a list rebuild)."""

    mass: float
    dt: float
    step0: int
    n_steps: int
    resume: bool


def pair_params(coeffs: np.ndarray, a: float, r_cut: float) -> tuple[PairParams, bool]:
    """The pair term's scalars for force coefficients `coeffs` (force.SevenRoot.coeffs), spacing a and
    cutoff r_cut (m), and whether the envelope is (a/r)^2 (the vectorised square; otherwise x^-p
    through pow)."""
    c = coeffs
    prm = PairParams(*(float(r) for r in c[C_ROOTS:C_ROOTS + 7]), amp_a=float(c[C_A]), step_lo=float(c[C_X0]),
                     inv_w=1.0 / (c[C_X1] - c[C_X0]), inv_a=1.0 / a, a=float(a), p=float(c[C_P]),
                     rc2=float(r_cut) ** 2)
    return prm, bool(c[C_PINT] == 2.0)


@njit(cache=True, inline="always", error_model="numpy")
def pair_term(dx, dy, dz, dvx, dvy, dvz, prm, delta, amp_a, p, square):
    """Force on i from j (seven-root F with force scale amp_a and envelope exponent p, + delta * rdot; 0
    from r_cut on), d = x_j - x_i, dv = v_j - v_i.

    Branch-free, as kernel_fast.py's `_group`: root factors multiplied as a depth-3 tree (A folded in),
    clamped STEP (0 from 2a on), envelope (a/r)^2 as (a * (1/r))^2 if square (a constant: every replica
    has p = 2), else chosen per pair: (a * (1/r))^2 where p == 2, (r/a)^-p elsewhere, so that a replica
    with p = 2 among others computes exactly what its single run (square) does."""
    r0, r1, r2, r3, r4, r5, r6, _, step_lo, inv_w, inv_a, a, _, rc2 = prm
    rr = dx * dx + dy * dy + dz * dz
    r = math.sqrt(rr)
    ir = 1.0 / r
    ex = dx * ir
    ey = dy * ir
    ez = dz * ir
    x = r * inv_a
    if square:
        f = force_tree(x, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, True)
    else:
        f = force_tree(x, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, p == 2.0)
    g = f + delta * (dvx * ex + dvy * ey + dvz * ez)
    g = g if rr < rc2 else 0.0
    return g * ex, g * ey, g * ez


@njit(inline="always")
def _slots(xs, vs, fs, s0, s1, o, buf, sl, prm, square):
    """f[:, s] += pair term of slot s (pair (s, s + o) of the flat index) for s in [s0, s1), kept in
    buf[:, s - s0]; sl (3, TILE * K): damping, force scale and exponent of each slot of a tile.  One
    contiguous loop, no call and no branch in its body (with square), so LLVM vectorises it.
    Indices are unsigned (no numba wrap-around code); o < 0 (gather) is fine while s + o >= 0."""
    x, y, z = xs[0], xs[1], xs[2]
    vx, vy, vz = vs[0], vs[1], vs[2]
    fx, fy, fz = fs[0], fs[1], fs[2]
    bx, by, bz = buf[0], buf[1], buf[2]
    dl, al, pl = sl[0], sl[1], sl[2]
    for s in range(s0, s1):
        i = np.uint64(s)
        j = np.uint64(s + o)
        q = np.uint64(s - s0)
        tx, ty, tz = pair_term(x[j] - x[i], y[j] - y[i], z[j] - z[i], vx[j] - vx[i], vy[j] - vy[i], vz[j] - vz[i],
                               prm, dl[q], al[q], pl[q], square)
        fx[i] += tx
        fy[i] += ty
        fz[i] += tz
        bx[q] = tx
        by[q] = ty
        bz[q] = tz


@njit(inline="always")
def _subtract(fs, buf, s0, s1, o):
    """f[:, s + o] -= buf[:, s - s0] for s in [s0, s1): the other particle's share (contiguous loops)."""
    for d in range(3):
        f = fs[d]
        b = buf[d]
        for s in range(s0, s1):
            f[np.uint64(s + o)] -= b[np.uint64(s - s0)]


@njit(inline="always")
def _tile(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton, square):
    """The group pairs of particles [t0, t1) (all K = nk replicas): with newton, pairs (i, i + o), each
    once, added to i and subtracted from i + o; without, (i, i + o) and (i, i - o), each pair twice,
    i writes only its own slot.  Loops inlined (numba IR): no call per group."""
    for g in range(offsets.shape[0]):
        o = offsets[g]
        e = min(t1, n - o)
        if e > t0:
            _slots(xs, vs, fs, t0 * nk, e * nk, o * nk, buf, sl, prm, square)
            if newton:
                _subtract(fs, buf, t0 * nk, e * nk, o * nk)
        b = max(t0, o)
        if not newton and t1 > b:
            _slots(xs, vs, fs, b * nk, t1 * nk, -o * nk, buf, sl, prm, square)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _tile_p2(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton):
    """`_tile` with the envelope (a/r)^2 (the vectorised loops)."""
    _tile(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton, True)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _tile_any(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton):
    """`_tile` with the envelope chosen per slot, (r/a)^-p through pow unless p == 2 (any p; correct,
    slower)."""
    _tile(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton, False)


@njit(inline="always")
def _tile_pass(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, square, newton):
    """The tile function of the envelope `square` (a constant: numba prunes the other branch, so only the
    envelope in use is compiled)."""
    if square:
        _tile_p2(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton)
    else:
        _tile_any(xs, vs, fs, t0, t1, n, nk, offsets, buf, sl, prm, newton)


@njit(cache=True, parallel=True, error_model="numpy")
def _residual_rows(xs, vs, fs, start, index, nk, delta, amp_a, p_env, prm, square):
    """f[:, i, k] += sum of row i of the residual list (full rows, ascending j), replica k; pairs at or
    beyond r_cut skipped (not added as zeros: extra pairs of a merged list change no bit)."""
    rc2 = prm[13]
    for i in prange(start.shape[0] - 1):
        for k in range(nk):
            si = i * nk + k
            fx = 0.0
            fy = 0.0
            fz = 0.0
            for p in range(start[i], start[i + 1]):
                sj = index[p] * nk + k
                dx = xs[0, sj] - xs[0, si]
                dy = xs[1, sj] - xs[1, si]
                dz = xs[2, sj] - xs[2, si]
                if dx * dx + dy * dy + dz * dz < rc2:
                    tx, ty, tz = pair_term(dx, dy, dz, vs[0, sj] - vs[0, si], vs[1, sj] - vs[1, si],
                                           vs[2, sj] - vs[2, si], prm, delta[k], amp_a[k], p_env[k], square)
                    fx += tx
                    fy += ty
                    fz += tz
            fs[0, si] += fx
            fs[1, si] += fy
            fs[2, si] += fz


@njit(inline="always")
def _forces(state, nl, replicas, prm, square):
    """fs = pair forces; state (3, N * K), replica innermost (flat index i * K + k), K = len(delta).

    Group pairs first, in tiles of TILE particles: block > 0, slabs: each pair once, blocks of width
    `block` (>= the largest offset) in two colours, so a block writes only into itself and the next;
    block = 0, gather: each pair twice, every tile on its own.  Then the residual rows (gather).
    The order of every sum is fixed by N, the offsets, block and TILE: independent of the thread
    count, and the same for each replica as for its single run (K = 1)."""
    xs, vs, fs = state.xs, state.vs, state.fs
    offsets, block, start, index = nl.offsets, nl.block, nl.start, nl.index
    delta, amp_a, p_env = replicas.delta, replicas.amp_a, replicas.p
    nk = delta.shape[0]
    n = xs.shape[1] // nk
    for s in prange(xs.shape[1]):
        fs[0, s] = 0.0
        fs[1, s] = 0.0
        fs[2, s] = 0.0
    sl = np.empty((3, TILE * nk))  # damping, A and p of slot q of a tile (tiles start at multiples of K)
    for q in range(TILE * nk):
        sl[0, q] = delta[q % nk]
        sl[1, q] = amp_a[q % nk]
        sl[2, q] = p_env[q % nk]
    if block > 0:
        nb = (n + block - 1) // block
        for colour in range(2):
            for q in prange((nb - colour + 1) // 2):
                b = 2 * q + colour
                buf = np.empty((3, TILE * nk))
                for t0 in range(b * block, min((b + 1) * block, n), TILE):
                    _tile_pass(xs, vs, fs, t0, min(t0 + TILE, (b + 1) * block, n), n, nk, offsets, buf, sl, prm,
                               square, True)
    else:
        for t in prange((n + TILE - 1) // TILE):
            buf = np.empty((3, TILE * nk))
            _tile_pass(xs, vs, fs, t * TILE, min((t + 1) * TILE, n), n, nk, offsets, buf, sl, prm, square, False)
    if index.shape[0] > 0:
        _residual_rows(xs, vs, fs, start, index, nk, delta, amp_a, p_env, prm, square)


@njit(cache=True, parallel=True, error_model="numpy")
def forces_p2(state: SlotState, nl: ListArrays, replicas: ReplicaParams, prm: PairParams) -> None:
    """`_forces` for the envelope (a/r)^2."""
    _forces(state, nl, replicas, prm, True)


@njit(cache=True, parallel=True, error_model="numpy")
def forces_any(state: SlotState, nl: ListArrays, replicas: ReplicaParams, prm: PairParams) -> None:
    """`_forces` for any envelope exponent p."""
    _forces(state, nl, replicas, prm, False)


@njit(cache=True, inline="always", error_model="numpy")
def _hold(xs, vs, x_rest, amp, s, i, kd, scale, omega, phase, t0, t1, inv_dt):
    """Slot s of held particle i after the drift: the drive over [t0, t1] with amplitude amp[i] * scale
    (PRESCRIBED) or rest (FROZEN: x_rest, v = 0).  Single runs pass scale 1.0 (amp * 1.0 is amp)."""
    if kd == PRESCRIBED:
        s0 = math.sin(omega * t0 + phase)
        s1 = math.sin(omega * t1 + phase)
        for d in range(3):
            ak = amp[i, d] * scale
            vs[d, s] = ak * (s1 - s0) * inv_dt
            xs[d, s] = x_rest[i, d] + ak * s1
    else:
        for d in range(3):
            vs[d, s] = 0.0
            xs[d, s] = x_rest[i, d]


@njit(cache=True, inline="always", error_model="numpy")
def _hold_velocity(vs, amp, s, i, kd, scale, omega, phase, t1):
    """Slot s of held particle i after the kick: the drive's velocity at t1 (PRESCRIBED) or 0 (FROZEN)."""
    if kd == PRESCRIBED:
        cs = math.cos(omega * t1 + phase)
        for d in range(3):
            vs[d, s] = amp[i, d] * scale * omega * cs
    else:
        for d in range(3):
            vs[d, s] = 0.0


@njit(inline="always")
def _over(px, py, pz, x_ref, q, lim2):
    """1 if position (px, py, pz) of slot q is more than sqrt(lim2) from x_ref[q] (or not finite), else 0."""
    r2 = (px - x_ref[q, 0]) ** 2 + (py - x_ref[q, 1]) ** 2 + (pz - x_ref[q, 2]) ** 2
    return 0 if r2 <= lim2 else 1


@njit(inline="always")
def _kick_v(vx, vy, vz, fx, fy, fz, q, h):
    """v += h f for slot q; returns the new v."""
    ux = vx[q] + h * fx[q]
    uy = vy[q] + h * fy[q]
    uz = vz[q] + h * fz[q]
    vx[q] = ux
    vy[q] = uy
    vz[q] = uz
    return ux, uy, uz


@njit(inline="always")
def _kick_slot(vx, vy, vz, fx, fy, fz, q, h, hot, hmk, dt, with_hot):
    """The closing kick of slot q: v += h f, and hot += m/2 |v|^2 dt with the new v if with_hot."""
    ux, uy, uz = _kick_v(vx, vy, vz, fx, fy, fz, q, h)
    if with_hot:
        hot[q] += hmk * (ux * ux + uy * uy + uz * uz) * dt


@njit(inline="always")
def _drift_slot(x, y, z, vx, vy, vz, fx, fy, fz, x_ref, q, h, dt, lim2):
    """v += h f, x += dt v for slot q; returns `_over` of the new position.  The count takes the values
    just computed: read back through the (3, N) state while the loop wrote its row views, the parallel
    loop saw stale positions (expiries missed, rebuilds a step late; numba 0.68, measured)."""
    ux, uy, uz = _kick_v(vx, vy, vz, fx, fy, fz, q, h)
    px = x[q] + dt * ux
    py = y[q] + dt * uy
    pz = z[q] + dt * uz
    x[q] = px
    y[q] = py
    z[q] = pz
    return _over(px, py, pz, x_ref, q, lim2)


@njit(cache=True, parallel=True, error_model="numpy")
def _kick_drift(xs, vs, fs, x_ref, hot, h, dt, hmk, lim2):
    """One pass over every slot as if it were free: the closing kick of a step (v += h f; hot += m/2 |v|^2
    dt if hot is not empty) and the drift of the next (v += h f, x += dt v).  Returns how many slots
    are now beyond sqrt(lim2) of x_ref.  One sweep over the state instead of three; contiguous loops
    over the flat index (vectorised)."""
    x, y, z = xs[0], xs[1], xs[2]
    vx, vy, vz = vs[0], vs[1], vs[2]
    fx, fy, fz = fs[0], fs[1], fs[2]
    with_hot = hot.shape[0] == x.shape[0]
    over = 0
    for q in prange(x.shape[0]):
        _kick_slot(vx, vy, vz, fx, fy, fz, q, h, hot, hmk, dt, with_hot)
        over += _drift_slot(x, y, z, vx, vy, vz, fx, fy, fz, x_ref, q, h, dt, lim2)
    return over


@njit(cache=True, parallel=True, error_model="numpy")
def _drift(xs, vs, fs, x_ref, h, dt, lim2):
    """The drift alone (first step of a call): v += h f, x += dt v; returns the count as `_kick_drift`."""
    x, y, z = xs[0], xs[1], xs[2]
    vx, vy, vz = vs[0], vs[1], vs[2]
    fx, fy, fz = fs[0], fs[1], fs[2]
    over = 0
    for q in prange(x.shape[0]):
        over += _drift_slot(x, y, z, vx, vy, vz, fx, fy, fz, x_ref, q, h, dt, lim2)
    return over


@njit(cache=True, parallel=True, error_model="numpy")
def _kick(vs, fs, hot, h, dt, hmk):
    """The closing kick alone (last step of a call): v += h f; hot += m/2 |v|^2 dt if hot is not empty."""
    vx, vy, vz = vs[0], vs[1], vs[2]
    fx, fy, fz = fs[0], fs[1], fs[2]
    with_hot = hot.shape[0] == vx.shape[0]
    for q in prange(vx.shape[0]):
        _kick_slot(vx, vy, vz, fx, fy, fz, q, h, hot, hmk, dt, with_hot)


@njit(inline="always")
def _advance(state, fixes, replicas, nl, prm, steps, square):
    """Velocity-Verlet steps of K replicas (K = len(scale); state (3, N * K), x_ref (N * K, 3)) from
    step0 until n_steps are done or the list expires.

    The closing kick of a step and the drift of the next run in one pass over every slot as if it
    were free (`_kick_drift`); the held particles (indices `held`, few) are then corrected: their hot
    sum, kick velocity, drive or rest and displacement count are redone exactly as a separate pass
    would have done them (bit for bit).  So are the bath particles (indices `bath`, an absorbing face):
    from their saved x_n and v_{n-1/2}, v_n = exp(-gamma dt) (v_{n-1/2} + dt/2 F_n / m) (the bath acts
    at the full step, velocity Verlet's halves around it unchanged), then the next half kick and drift.
    Returns (steps completed, status).  On EXPIRED the step in
    progress has been drifted (x at t_{n+1}, v = v_{n+1/2}) but has no forces yet: rebuild the list
    and call again with resume=True, which starts at the force pass.  hot (N * K) accumulates KE dt
    (if not empty).
    """
    xs, vs, fs, hot = state
    x_rest, kind, held, amp, phase, bath = fixes
    scale, omega, gamma = replicas.scale, replicas.omega, replicas.gamma
    x_ref, half_skin = nl.x_ref, nl.half_skin
    mass, dt, step0, n_steps, resume = steps
    nk = scale.shape[0]
    lim2 = half_skin * half_skin
    h = 0.5 * dt / mass
    inv_dt = 1.0 / dt
    hmk = 0.5 * mass
    with_hot = hot.shape[0] == xs.shape[1]
    saved = np.zeros(held.shape[0] * nk)
    nb = bath.shape[0]
    bath_x = np.zeros((nb * nk, 3))  # x_n and v_{n-1/2} of the bath slots before a pass, and their hot sums
    bath_v = np.zeros((nb * nk, 3))
    bath_hot = np.zeros(nb * nk)
    damp = np.empty(nk)
    for k in range(nk):
        damp[k] = math.exp(-gamma[k] * dt)
    if n_steps <= 0:
        return 0, DONE
    if not resume:  # drift of the first step
        over = _drift(xs, vs, fs, x_ref, h, dt, lim2)
        for p in range(held.shape[0]):
            i = held[p]
            for k in range(nk):
                q = i * nk + k
                over -= _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
                _hold(xs, vs, x_rest, amp, q, i, kind[i], scale[k], omega[k], phase[i], step0 * dt, (step0 + 1) * dt,
                      inv_dt)
                over += _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
        if over > 0:
            return 0, EXPIRED
    s = 0
    while True:
        if square:
            forces_p2(state, nl, replicas, prm)
        else:
            forces_any(state, nl, replicas, prm)
        s += 1
        t1 = (step0 + s) * dt  # end of step s, start of step s + 1 (times as n * dt, never summed)
        t2 = (step0 + s + 1) * dt
        last = s == n_steps
        if with_hot:
            for p in range(held.shape[0]):
                for k in range(nk):
                    saved[p * nk + k] = hot[held[p] * nk + k]
        for p in range(nb):
            for k in range(nk):
                q = bath[p] * nk + k
                for d in range(3):
                    bath_x[p * nk + k, d] = xs[d, q]
                    bath_v[p * nk + k, d] = vs[d, q]
                if with_hot:
                    bath_hot[p * nk + k] = hot[q]
        over = 0
        if last:
            _kick(vs, fs, hot, h, dt, hmk)
        else:
            over = _kick_drift(xs, vs, fs, x_ref, hot, h, dt, hmk, lim2)
        for p in range(held.shape[0]):
            i = held[p]
            for k in range(nk):
                q = i * nk + k
                if not last:
                    over -= _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
                _hold_velocity(vs, amp, q, i, kind[i], scale[k], omega[k], phase[i], t1)
                if with_hot:
                    hot[q] = saved[p * nk + k] + hmk * (vs[0, q] * vs[0, q] + vs[1, q] * vs[1, q]
                                                        + vs[2, q] * vs[2, q]) * dt
                if not last:
                    _hold(xs, vs, x_rest, amp, q, i, kind[i], scale[k], omega[k], phase[i], t1, t2, inv_dt)
                    over += _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
        for p in range(nb):
            for k in range(nk):
                q = bath[p] * nk + k
                b = p * nk + k
                if not last:
                    over -= _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
                for d in range(3):
                    vs[d, q] = (bath_v[b, d] + h * fs[d, q]) * damp[k]
                if with_hot:
                    hot[q] = bath_hot[b] + hmk * (vs[0, q] * vs[0, q] + vs[1, q] * vs[1, q] + vs[2, q] * vs[2, q]) * dt
                if not last:
                    for d in range(3):
                        u = vs[d, q] + h * fs[d, q]
                        vs[d, q] = u
                        xs[d, q] = bath_x[b, d] + dt * u
                    over += _over(xs[0, q], xs[1, q], xs[2, q], x_ref, q, lim2)
        if last:
            return s, DONE
        if over > 0:
            return s, EXPIRED


@njit(cache=True, parallel=True, error_model="numpy")
def advance_p2(state: SlotState, fixes: DriveArrays, replicas: ReplicaParams, nl: ListArrays, prm: PairParams,
               steps: StepParams) -> tuple[int, int]:
    """`_advance` for the envelope (a/r)^2: (steps completed, DONE or EXPIRED)."""
    return _advance(state, fixes, replicas, nl, prm, steps, True)


@njit(cache=True, parallel=True, error_model="numpy")
def advance_any(state: SlotState, fixes: DriveArrays, replicas: ReplicaParams, nl: ListArrays, prm: PairParams,
                steps: StepParams) -> tuple[int, int]:
    """`_advance` for any envelope exponent p."""
    return _advance(state, fixes, replicas, nl, prm, steps, False)


@njit(cache=True, error_model="numpy")  # serial: a check, not a hot loop (compiles faster)
def _pair_sums(xs, offsets, start, index, c, a, rc2):
    """(interacting pairs i < j, U) of one replica (xs (3, N)): group slots and residual entries j > i
    with r < r_cut; U = sum of a * int_2^{r/a} F dx (0 at 2a), per particle, then in index order."""
    n = xs.shape[1]
    u = np.zeros(n)
    count = 0
    for g in range(offsets.shape[0]):
        o = offsets[g]
        for i in range(n - o):
            r2 = (xs[0, i + o] - xs[0, i]) ** 2 + (xs[1, i + o] - xs[1, i]) ** 2 + (xs[2, i + o] - xs[2, i]) ** 2
            if r2 < rc2:
                count += 1
                u[i] += energy_x(2.0, math.sqrt(r2) / a, c)
    for i in range(n):
        for p in range(start[i], start[i + 1]):
            j = index[p]
            r2 = (xs[0, j] - xs[0, i]) ** 2 + (xs[1, j] - xs[1, i]) ** 2 + (xs[2, j] - xs[2, i]) ** 2
            if j > i and r2 < rc2:
                count += 1
                u[i] += energy_x(2.0, math.sqrt(r2) / a, c)
    total = 0.0
    for i in range(n):
        total += u[i] * a
    return count, total


def pair_forces(x: np.ndarray, v: np.ndarray, nl: NeighbourList, model: SevenRoot, a: float, delta: float,
                r_cut: float | None = None, force_pass: str = "slabs") -> np.ndarray:
    """Forces (N, 3) at positions x and velocities v (N, 3) from list nl (r_cut default nl.r_cut): the
    kernel's force pass, for checks and tests."""
    prm, square = pair_params(model.coeffs(), a, nl.r_cut if r_cut is None else r_cut)
    xs, vs = np.ascontiguousarray(x.T), np.ascontiguousarray(v.T)
    fs = np.empty_like(xs)
    state = SlotState(xs=xs, vs=vs, fs=fs, hot=np.zeros(0))
    lists = ListArrays(offsets=nl.offsets, block=slab_block(nl) if force_pass == "slabs" else 0, start=nl.start,
                       index=nl.index, x_ref=nl.x_ref, half_skin=0.5 * nl.skin)
    replicas = ReplicaParams(scale=np.ones(1), omega=np.zeros(1), delta=np.array([float(delta)]),
                             amp_a=np.array([prm.amp_a]), p=np.array([prm.p]), gamma=np.zeros(1))
    (forces_p2 if square else forces_any)(state, lists, replicas, prm)
    return fs.T.copy()


def slab_block(nl: NeighbourList) -> int:
    """Slab block width of a list's groups: at least the largest offset and TILE (fixed by the groups)."""
    return max(nl.reach, TILE)


def check_range(r_cut: float, skin: float, dt: float) -> None:
    """SceneError unless 2 < r_cut <= 4 (units of a), 0 < skin <= 2 (units of a) and 0 < dt (s)."""
    if not (math.isfinite(r_cut) and 2.0 < r_cut <= 4.0):
        raise SceneError(f"r_cut={r_cut!r} (units of a) is out of range; allowed: number in (2, 4] (the force "
                         "ends at 2a; pairs resting at 2a must stay inside the interaction range)")
    if not (math.isfinite(skin) and 0.0 < skin <= 2.0):
        raise SceneError(f"skin={skin!r} (units of a) is out of range; allowed: number in (0, 2]")
    if not (math.isfinite(dt) and dt > 0.0):
        raise SceneError(f"dt={dt!r} is out of range; allowed: number in (0, inf) s")


def initial_state(x_rest: np.ndarray, kind: np.ndarray | None, amp: np.ndarray | None, phase: np.ndarray | None,
                  x0: np.ndarray | None, v0: np.ndarray | None) -> tuple[np.ndarray, ...]:
    """(x_rest, kind, amp, phase, x, v): rest positions and fixes as contiguous arrays (defaults: every
    particle FREE, no drive) and the initial state of the undriven particles (x0 default x_rest, v0
    default 0; FROZEN ones at rest).  Driven particles are placed by the caller (single run or replicas)."""
    n = x_rest.shape[0]
    x_rest = np.ascontiguousarray(x_rest, dtype=np.float64)
    kind = np.zeros(n, dtype=np.int8) if kind is None else np.ascontiguousarray(kind, dtype=np.int8)
    bad = ~np.isin(kind, KINDS)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SceneError(f"kind[{i}]={int(kind[i])} is not allowed; allowed: "
                         f"{', '.join(f'{k} ({KIND_NAMES[k]})' for k in KINDS)}")
    amp = np.zeros((n, 3)) if amp is None else np.ascontiguousarray(amp, dtype=np.float64)
    phase = np.zeros(n) if phase is None else np.ascontiguousarray(phase, dtype=np.float64)
    x = x_rest.copy() if x0 is None else np.array(x0, dtype=np.float64)
    x[kind == FROZEN] = x_rest[kind == FROZEN]
    v = np.zeros((n, 3)) if v0 is None else np.array(v0, dtype=np.float64)
    v[kind == FROZEN] = 0.0
    return x_rest, kind, amp, phase, x, v


def soa_state(x: np.ndarray, k: int) -> np.ndarray:
    """(3, N, K) contiguous copy of positions or velocities (N, K, 3) or (N, 3) (then K copies)."""
    x = np.asarray(x, dtype=np.float64)
    return np.ascontiguousarray(np.broadcast_to(x.reshape(x.shape[0], -1, 3), (x.shape[0], k, 3)).transpose(2, 0, 1))


@dataclass(eq=False, kw_only=True)
class LatticeRun:
    """State shared by the runs of the large-N kernel (single run: K = 1, ensemble: K replicas) and their
    step driver: `advance` calls the kernel until the list expires, checks the state, rebuilds the list
    and resumes at the force pass.  State xs, vs, fs is (3, N, K) (structure of arrays, replica
    innermost); x, v, f are (N, K, 3) views of it."""

    xs: np.ndarray
    vs: np.ndarray
    fs: np.ndarray
    x_rest: np.ndarray
    kind: np.ndarray
    amp: np.ndarray
    phase: np.ndarray
    mass: float
    a: float
    dt: float
    coeffs: np.ndarray
    nl: NeighbourList
    hot: np.ndarray
    r_cut: float
    force_pass: str = "slabs"
    step: int = 0
    status: str = "ok"
    reason: str = ""
    bath: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # absorbing-bath particles

    @property
    def x(self) -> np.ndarray:
        return self.xs.transpose(1, 2, 0)

    @property
    def v(self) -> np.ndarray:
        return self.vs.transpose(1, 2, 0)

    @property
    def f(self) -> np.ndarray:
        return self.fs.transpose(1, 2, 0)

    @property
    def size(self) -> int:
        return int(self.xs.shape[1])

    @property
    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The bar's neighbourhood (rest box widened by a on every side), computed once per run: numpy's
        min and max over axis 0 of an (N, 3) array are strided reductions, too slow for every call."""
        if getattr(self, "_bounds_for", None) is not self.x_rest:
            self._bounds = (self.x_rest.min(axis=0) - self.a, self.x_rest.max(axis=0) + self.a)
            self._bounds_for = self.x_rest
        return self._bounds

    @property
    def held(self) -> np.ndarray:
        """Indices of the held (FROZEN, PRESCRIBED) particles."""
        if getattr(self, "_held_for", None) is not self.kind:
            self._held = np.flatnonzero(self.kind != FREE)
            self._held_for = self.kind
        return self._held

    @property
    def block(self) -> int:
        """Slab block width (0: gather pass); fixed by the list's groups."""
        return 0 if self.force_pass == "gather" else slab_block(self.nl)

    def _vectors(self) -> tuple[ReplicaParams, np.ndarray]:
        """The parameter set of every replica and the list's reference positions (N * K, 3)."""
        raise NotImplementedError

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        """Why the state is unstable (non-finite, or a particle outside [lo, hi]); "" if it is not."""
        raise NotImplementedError

    def _rebuild(self, step: int) -> None:
        raise NotImplementedError

    def _kernel_args(self) -> tuple[SlotState, ListArrays, ReplicaParams, PairParams, bool]:
        """The kernels' structures for the current state and list, and whether the envelope is (a/r)^2 for
        every replica (then the vectorised square envelope is compiled, else the one chosen per pair)."""
        replicas, x_ref = self._vectors()
        prm, _ = pair_params(self.coeffs, self.a, self.r_cut)
        square = bool(np.all(replicas.p == 2.0))
        state = SlotState(xs=self.xs.reshape(3, -1), vs=self.vs.reshape(3, -1), fs=self.fs.reshape(3, -1),
                          hot=self.hot.reshape(-1))
        lists = ListArrays(offsets=self.nl.offsets, block=self.block, start=self.nl.start, index=self.nl.index,
                           x_ref=x_ref, half_skin=0.5 * self.nl.skin)
        return state, lists, replicas, prm, square

    def _forces(self) -> None:
        state, lists, replicas, prm, square = self._kernel_args()
        (forces_p2 if square else forces_any)(state, lists, replicas, prm)

    def _steps(self, n_steps: int, resume: bool) -> tuple[int, int]:
        """Run the numba kernel from self.step: (steps completed, DONE or EXPIRED)."""
        state, lists, replicas, prm, square = self._kernel_args()
        fixes = DriveArrays(x_rest=self.x_rest, kind=self.kind, held=self.held, amp=self.amp, phase=self.phase,
                            bath=self.bath)
        steps = StepParams(mass=self.mass, dt=self.dt, step0=self.step, n_steps=int(n_steps), resume=bool(resume))
        return (advance_p2 if square else advance_any)(state, fixes, replicas, lists, prm, steps)

    def advance(self, n_steps: int) -> int:
        """Advance n_steps (fewer if the run becomes unstable: status, reason set, sums kept); rebuilds the
        list on demand."""
        done = 0
        resume = False
        lo, hi = self.bounds
        while done < n_steps and self.status == "ok":
            s, code = self._steps(n_steps - done, resume)
            done += s
            self.step += s
            resume = False
            if code == EXPIRED:
                reason = self._instability(lo, hi)
                if reason:
                    self.status, self.reason = "unstable", reason
                else:
                    self._rebuild(self.step)
                    resume = True
        if resume:  # stopped between drift and forces: finish the step
            self._steps(1, True)
            done += 1
            self.step += 1
        return done

    @property
    def nbytes(self) -> int:
        """Memory of the run's arrays: state, fixes, sums and the neighbour list (bytes)."""
        arrays = (self.xs, self.vs, self.fs, self.x_rest, self.kind, self.amp, self.phase, self.hot)
        return int(sum(a.nbytes for a in arrays) + self.nl.nbytes)


@dataclass(eq=False, kw_only=True)
class KernelRun(LatticeRun):
    """State of one run of the large-N kernel (positions, velocities, forces, list, fixes, sums)."""

    omega: float
    delta: float

    @classmethod
    def start(cls, x_rest: np.ndarray, mass: float, a: float, model: SevenRoot, delta: float, dt: float,
              v0: np.ndarray | None = None, x0: np.ndarray | None = None, kind: np.ndarray | None = None,
              amp: np.ndarray | None = None, phase: np.ndarray | None = None, omega: float = 0.0,
              r_cut: float = DEFAULT_R_CUT, skin: float = DEFAULT_SKIN, hotness: bool = False,
              force_pass: str = "slabs", groups: bool = True) -> KernelRun:
        """Set up a run at t = 0: list built on x0 (default x_rest), forces F(x0, v0) computed.  groups:
        offset groups from the rest lattice (`neighbours.stencil_offsets`); False: residual list only."""
        check_range(r_cut, skin, dt)
        if force_pass not in FORCE_PASSES:
            raise SceneError(f"force_pass={force_pass!r} is not allowed; allowed: {', '.join(FORCE_PASSES)}")
        if not (math.isfinite(delta) and delta >= 0.0):
            raise SceneError(f"delta={delta!r} is out of range; allowed: number in [0, inf) N s/m")
        x_rest, kind, amp, phase, x, v = initial_state(x_rest, kind, amp, phase, x0, v0)
        n = x_rest.shape[0]
        drv = kind == PRESCRIBED
        x[drv] = x_rest[drv] + amp[drv] * np.sin(phase[drv])[:, None]
        v[drv] = amp[drv] * (omega * np.cos(phase[drv]))[:, None]
        offsets = stencil_offsets(x_rest, (r_cut + skin) * a) if groups else None
        nl = build_neighbours(x, r_cut * a, skin * a, offsets)
        run = cls(xs=soa_state(x, 1), vs=soa_state(v, 1), fs=np.zeros((3, n, 1)), x_rest=x_rest, kind=kind, amp=amp,
                  phase=phase, omega=float(omega), mass=float(mass), a=float(a), dt=float(dt), coeffs=model.coeffs(),
                  delta=float(delta), nl=nl, hot=np.zeros(n if hotness else 0), r_cut=float(r_cut) * a,
                  force_pass=force_pass)
        run._forces()
        return run

    @property
    def x(self) -> np.ndarray:
        return self.xs[:, :, 0].T

    @property
    def v(self) -> np.ndarray:
        return self.vs[:, :, 0].T

    @property
    def f(self) -> np.ndarray:
        return self.fs[:, :, 0].T

    def _vectors(self) -> tuple[ReplicaParams, np.ndarray]:
        return ReplicaParams(scale=np.ones(1), omega=np.array([self.omega]), delta=np.array([self.delta]),
                             amp_a=np.array([self.coeffs[C_A]]), p=np.array([self.coeffs[C_P]]),
                             gamma=np.zeros(1)), self.nl.x_ref

    def _instability(self, lo: np.ndarray, hi: np.ndarray) -> str:
        if not np.isfinite(self.xs).all() or not np.isfinite(self.vs).all():
            return f"NaN/Inf in the state at step {self.step}; sums kept"
        if (self.x < lo).any() or (self.x > hi).any():
            return f"a particle left the bar's neighbourhood (more than a outside) at step {self.step}; sums kept"
        return ""

    def _rebuild(self, step: int) -> None:
        self.nl.rebuild(self.x, step)

    def pair_count(self) -> int:
        """Interacting pairs (i < j, r < r_cut) at the current positions."""
        return int(_pair_sums(self.xs[:, :, 0], self.nl.offsets, self.nl.start, self.nl.index, self.coeffs, self.a,
                              self.r_cut**2)[0])

    def potential_energy(self) -> float:
        """U(x) (J) with U = 0 for pairs at 2a; summed per particle, then in index order (deterministic)."""
        return float(_pair_sums(self.xs[:, :, 0], self.nl.offsets, self.nl.start, self.nl.index, self.coeffs,
                                self.a, self.r_cut**2)[1])

    def kinetic_energy(self) -> float:
        return float(0.5 * self.mass * np.einsum("ij,ij->", self.v, self.v))


def bench_lattice(n: int, box: Box | None = None, density: float = 2800.0) -> tuple[np.ndarray, float, float]:
    """Rest positions (N, 3), spacing a and particle mass of the lattice n x n x (3n-2) in the bar."""
    box = box or Box()
    x = box.lattice_points(n)
    return x, box.lattice_spacing(n), density * box.volume / x.shape[0]


def omega_bound(model: SevenRoot, a: float, mass: float) -> float:
    """Upper bound on the lattice's highest angular frequency (Gershgorin on the rest Hessian).

    At rest every pair sits on a root, so its Hessian block is k_s e e^T (k_s = dF/dr of its
    shell); the absolute row sum of a bulk particle's rows is at most 2 sum_s k_s N_s max_c
    sum_b |e_c e_b|, with N_s neighbours in shell s.  Cheap at any N (no eigenproblem).
    """
    k = np.abs(shell_stiffness(model, a))
    offsets = np.array([(i, j, m) for i in (-2, -1, 0, 1, 2) for j in (-2, -1, 0, 1, 2) for m in (-2, -1, 0, 1, 2)
                        if 0 < i * i + j * j + m * m <= 4], dtype=float)
    r = np.linalg.norm(offsets, axis=1)
    e = offsets / r[:, None]
    shell = np.rint(r**2).astype(int) - 1  # 1, 2, 3, 4 -> shells 0..3
    ks = k[shell]
    row = np.abs(e[:, :, None] * e[:, None, :]).sum(axis=2)  # (P, 3): sum_b |e_c e_b| for each c
    bound = 2.0 * (ks[:, None] * row).sum(axis=0).max()
    return math.sqrt(bound / mass)
