"""The macromolecule integrator: one kernel, its inputs, its pair pass and its step with fixes and computes.

Kick-drift velocity Verlet with radial pair damping at the half-step velocity, one force pass per step, and an
exact energy ledger (scheme, stability limit and why the default safety is 0.05: docs/physics.md, "The
macromolecule model").  The pair list is a lattice stencil (contiguous, masked slots) so LLVM vectorises the pair
loop; dissipation is kept per slot and summed in 8 fixed partial sums; compiled per envelope: `run_p2`, `run_any`.
"""

from __future__ import annotations

import math
from collections import namedtuple

import llvmlite.binding as llvm
import numpy as np
from numba import njit

from .codes import (
    E_START,
    FREE,
    FROZEN,
    GROUP,
    K_FIRST_HOP,
    K_HALF1,
    K_HALF2,
    K_HOT_STEPS,
    K_STATIONARY,
    K_STATUS,
    RUNNING,
)
from .computes import check, finish, hops, hot_sums, neighbourhood, potential_any, potential_p2, record, sum8
from .fixes import bath_kick, drive_positions, fix_work, held_kick, start_velocity
from .force import C_A, C_P, C_ROOTS, C_X0, C_X1, pair_force

# LLVM's default limit on runtime alias checks keeps the group loop (16 arrays read, 8 written) scalar; raising
# it changes which loops vectorise, never a result (no fastmath, no floating-point reductions in them).
llvm.set_option("", "-vectorize-memory-check-threshold=4096")


# The kernel's five inputs (named tuples; arrays C-contiguous float64 / int64 / int8: one compiled signature and
# cache entry serve every run).  RunState: start positions and velocities (N, 3), overwritten with the final ones.
# LatticeArrays: rest positions, mass, spacing, the pairs (i < j), the stencil (per group: offset, first slot, root
# interval [lo, hi) in units of a, rest distance; per slot: 0/1 mask, rest distance; each pair's slot).
# FixArrays: fix kinds (codes), drive amplitudes (N, 3) and phases, Langevin friction and kT, the drive's angular
# frequency, whether the red pair's centre moves freely, the seed.  RunParams: force coefficients, damping, dt,
# steps, hotness window [n_start, n_end), check interval, blow-up rule (kinetic energy above blowup_factor times
# the energy supplied plus e_scale), the bar's box, the neighbourhood check (contact fraction of a, largest rest
# distance listed, skin), the window's marks and the stationarity stop (`simulate.window_marks`: at each mark the
# window's halves are compared).  RunOutputs: hot (3, N) sums of KE dt over the window and its halves, energy
# (codes.E_*), counters (codes.K_*), history (codes.H_*), ever (P,): 1 for pairs that ever hopped.
RunState = namedtuple("RunState", "x v")
LatticeArrays = namedtuple("LatticeArrays", "x_rest mass a pi pj g_off g_base g_lo g_hi g_r0 mask r0s slot")
FixArrays = namedtuple("FixArrays", "kind amp phase gamma kt omega free_centre seed")
RunParams = namedtuple("RunParams", "coeffs delta dt n_steps n_start n_end check_every blowup_factor e_scale box_lo "
                                    "box_hi contact_fraction cutoff_rest skin marks stop_tol")
RunOutputs = namedtuple("RunOutputs", "hot energy counters history ever")


def stencil(pairs: np.ndarray, shell: np.ndarray, n: int, basins: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pair list as groups of equal index offset o = j - i and rest shell (a lattice stencil).

    Group g covers the slots i = 0 .. n - o - 1 (pair (i, i + o)) at slots base_g + i; slots that are
    not listed pairs (lattice edges) have mask 0 and contribute exactly nothing.  Returns (offset, base,
    lo, hi) per group, the slot mask and each listed pair's slot."""
    off = pairs[:, 1] - pairs[:, 0]
    keys, gidx = np.unique(off * 4 + shell, return_inverse=True)
    g_off = (keys // 4).astype(np.int64)
    base = np.concatenate([[0], np.cumsum(n - g_off)]).astype(np.int64)
    slot = (base[gidx] + pairs[:, 0]).astype(np.int64)
    mask = np.zeros(base[-1])
    mask[slot] = 1.0
    return g_off, base, basins[keys % 4, 0].copy(), basins[keys % 4, 1].copy(), mask, slot


def lattice_arrays(x_rest: np.ndarray, mass: float, a: float, pairs: np.ndarray, r0: np.ndarray, shell: np.ndarray,
                   basins: np.ndarray) -> LatticeArrays:
    """The kernel's lattice for pairs (P, 2), their rest distances and shells and the model's root
    intervals per shell (force.SevenRoot.basins)."""
    g_off, g_base, g_lo, g_hi, mask, slot = stencil(pairs, shell, x_rest.shape[0], basins)
    r0s = np.zeros(mask.shape[0])
    r0s[slot] = r0
    g_r0 = np.zeros(g_off.shape[0])
    g_r0[np.searchsorted(g_base, slot, side="right") - 1] = r0  # a group's pairs share their rest shell
    return LatticeArrays(
        x_rest=np.ascontiguousarray(x_rest, dtype=np.float64), mass=float(mass), a=float(a),
        pi=np.ascontiguousarray(pairs[:, 0], dtype=np.int64), pj=np.ascontiguousarray(pairs[:, 1], dtype=np.int64),
        g_off=g_off, g_base=g_base, g_lo=g_lo, g_hi=g_hi, g_r0=g_r0, mask=mask, r0s=r0s, slot=slot)


@njit(inline="always")
def _group(pos, vel, o, base, lo, hi, mask, rt, shape, a, delta, dt, qk, dk, out, fi, fj, square):
    """One stencil group: each slot's damped pair force added to fi[i] and subtracted from fj[i + o], its
    dissipation term added to dk (damping force over distance kept in qk); returns how many slots changed
    their hop flag against `out`.  No inner loop or call in the body, unsigned indices: it vectorises."""
    px, py, pz = pos
    vx, vy, vz = vel
    fix, fiy, fiz = fi
    fjx, fjy, fjz = fj
    amp_a, p, step_lo, inv_w = shape
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    changed = 0
    for i in range(px.shape[0] - o):
        s, iu, j = np.uint64(base + i), np.uint64(i), np.uint64(i + o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        ir = 1.0 / r
        ex, ey, ez = dx * ir, dy * ir, dz * ir
        x = r * inv_a
        f = pair_force(x, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square) * m
        dvx, dvy, dvz = vx[j] - vx[iu], vy[j] - vy[iu], vz[j] - vz[iu]
        rdot = dvx * ex + dvy * ey + dvz * ez
        g = delta * rdot * m
        dk[s] += qk[s] * (r * rdot - dt * (dvx * dvx + dvy * dvy + dvz * dvz)) + g * rdot
        qk[s] = g * ir
        f += g
        tx, ty, tz = f * ex, f * ey, f * ez
        fix[iu] += tx
        fiy[iu] += ty
        fiz[iu] += tz
        fjx[j] -= tx
        fjy[j] -= ty
        fjz[j] -= tz
        flag = np.int8(1) if ((x < lo) | (x >= hi)) & (m != 0.0) else np.int8(0)
        changed += flag != out[s]
    return changed


@njit(inline="always")
def pair_pass(pos, vel, lattice, rt, shape, delta, dt, qk, dk, out, ever, step, counters, fi, fj, f, square):
    """Forces at the current positions (damping with the given velocities) into f = fi + fj; each slot's
    dissipation term over the interval ending here added to dk; hop flags exact, every slot, every pass."""
    fix, fiy, fiz = fi
    fjx, fjy, fjz = fj
    fx, fy, fz = f
    px, py, pz = pos
    for i in range(fx.shape[0]):
        fix[i] = fiy[i] = fiz[i] = fjx[i] = fjy[i] = fjz[i] = 0.0
    g_off, g_base, g_lo, g_hi, mask, a = lattice.g_off, lattice.g_base, lattice.g_lo, lattice.g_hi, lattice.mask, \
        lattice.a
    for g in range(g_off.shape[0]):
        changed = _group(pos, vel, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, rt, shape, a, delta, dt, qk, dk, out,
                         fi, fj, square)
        if changed != 0:
            hops(px, py, pz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, a, out, ever, step, counters)
    for i in range(fx.shape[0]):
        fx[i], fy[i], fz[i] = fix[i] + fjx[i], fiy[i] + fjy[i], fiz[i] + fjz[i]


@njit(inline="always")
def _stationary(hot1, hot2, c1, c2, kind, gamma, tol):
    """Whether the halves' mean hotness (sums hot1 over c1 steps, hot2 over c2) of every free particle (no fix,
    no bath) agree within tol of the hottest free particle's mean over the whole window."""
    hmax = diff = 0.0
    for i in range(hot1.shape[0]):
        if kind[i] == FREE and gamma[i] == 0.0:
            hmax = max(hmax, (hot1[i] + hot2[i]) / (c1 + c2))
            diff = max(diff, abs(hot1[i] / c1 - hot2[i] / c2))
    return hmax > 0.0 and diff <= tol * hmax


@njit(cache=True)
def _xyz(n):
    """x, y and z vectors of length n, zero (structure of arrays: three separate allocations)."""
    return np.zeros(n), np.zeros(n), np.zeros(n)


@njit(inline="always")
def _run(state, lattice, fixes, params, out, square, potential):
    """The step loop.  `square` (a constant) picks the envelope, `potential` the matching energy function."""
    x, v0 = state
    x_rest, mass = lattice.x_rest, lattice.mass
    kind, amp, phase, gamma, kt, omega, free_centre, seed = fixes
    c, delta, dt, n_steps, n_start, n_end = params.coeffs, params.delta, params.dt, params.n_steps, params.n_start, \
        params.n_end
    hot, energy, counters, history, ever = out
    np.random.seed(seed)  # noqa: NPY002 (numba supports only the legacy seeded RNG in kernels)
    n = x.shape[0]
    pos = (np.ascontiguousarray(x[:, 0]), np.ascontiguousarray(x[:, 1]), np.ascontiguousarray(x[:, 2]))
    px, py, pz = pos
    rt = c[C_ROOTS:C_ROOTS + 7].copy()
    shape = (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]))
    held, free = np.flatnonzero(kind != FREE), np.flatnonzero(kind == FREE)
    bath, moving = np.flatnonzero((kind == FREE) & (gamma > 0.0)), np.flatnonzero((kind != FREE) & (kind != FROZEN))
    group_mass = mass * np.sum(kind == GROUP)
    if group_mass == 0.0:
        free_centre = False
    f, fi, fj, vm, vp = _xyz(n), _xyz(n), _xyz(n), _xyz(n), _xyz(n)
    fx, fy, fz = f
    ns = lattice.mask.shape[0]
    qk, dk, es = np.zeros(ns), np.zeros(ns), np.zeros(ns)  # per slot: damping force / r, dissipation, energy
    ever_s, out_s = np.zeros(ns, dtype=np.int8), np.zeros(ns, dtype=np.int8)  # hop flags: ever, now
    lh0, lh1 = np.zeros((held.shape[0], 3)), np.zeros((held.shape[0], 3))  # lambda of held and bath particles
    lb0, lb1 = np.zeros((bath.shape[0], 3)), np.zeros((bath.shape[0], 3))
    vc, cpos = np.zeros(3), np.zeros(3)  # the red pair's centre: velocity, displacement
    hot1, hot2 = np.zeros(n), np.zeros(n)
    counters[:] = 0
    counters[K_FIRST_HOP], counters[K_STATUS], counters[K_STATIONARY] = -1, RUNNING, -1  # no hop yet, running
    energy[:] = 0.0
    marks, mark = params.marks, 0  # the window's next mark: marks[mark]
    half_m, dtm = 0.5 * mass, dt / mass
    vpx, vpy, vpz = vp
    for i in range(n):
        vpx[i], vpy[i], vpz[i] = v0[i, 0], v0[i, 1], v0[i, 2]
    w_drive = w_bath = 0.0  # work done by drives and baths so far
    hrow, step, status = 0, 0, RUNNING
    while True:
        # --- forces at t_n with damping from v_{n-1/2} (at the start: v0); dissipation over n-1 -> n into dk.
        # One call site for every pass, so that the pair loops are compiled once
        pair_pass(pos, vp, lattice, rt, shape, delta, dt, qk, dk, out_s, ever_s, step, counters, fi, fj, f, square)
        if step == 0:
            start_velocity(v0, f, vm, kind, held, free, amp, phase, omega, dt, dtm, vc, group_mass, free_centre)
            dk[:] = 0.0  # dissipation counts from the first interval on
        else:
            vm, vp = vp, vm  # v_{n-1/2} was the velocity of the drift
        vmx, vmy, vmz = vm
        vpx, vpy, vpz = vp
        t = step * dt
        # --- kick: v_{n+1/2} from v_{n-1/2} and F_n over all particles (one contiguous, vectorised loop);
        # held and bath particles are then overwritten by their fixes
        for i in range(n):
            vpx[i], vpy[i], vpz[i] = vmx[i] + dtm * fx[i], vmy[i] + dtm * fy[i], vmz[i] + dtm * fz[i]
        held_kick(t + dt, t, dt, kind, held, amp, phase, omega, mass, f, vm, vp, lh1, vc, group_mass, free_centre)
        bath_kick(dt, bath, gamma, kt, mass, f, vm, vp, lb1)
        if step == 0:
            e0 = 0.0
            for i in range(n):
                e0 += vmx[i] * vpx[i] + vmy[i] * vpy[i] + vmz[i] * vpz[i]
            energy[E_START] = half_m * e0 + potential(px, py, pz, lattice, c, es)
        else:  # drive and bath work over n-1 -> n with v_{n-1/2}
            w_drive += 0.5 * dt * fix_work(held, vm, lh0, lh1)
            w_bath += 0.5 * dt * fix_work(bath, vm, lb0, lb1)
        lh0, lh1 = lh1, lh0
        lb0, lb1 = lb1, lb0
        if step == n_steps:
            break
        # --- checks at t_n (every check_every steps)
        if step % params.check_every == 0:
            status, kin, bad = check(pos, vm, vp, params.box_lo, params.box_hi, half_m, energy[E_START] + w_drive
                                     + w_bath, params.blowup_factor, params.e_scale)
            if status == RUNNING:
                status = neighbourhood(px, py, pz, x_rest, kind, lattice.pi, lattice.pj, lattice.a,
                                       params.cutoff_rest, params.contact_fraction, params.skin)
            if hrow < history.shape[0]:
                pot = potential(px, py, pz, lattice, c, es) if not bad else np.nan
                record(history, hrow, t, kin, pot, 0.5 * dt * sum8(dk), w_drive, w_bath)
                hrow += 1
            if status != RUNNING:
                break
        # --- hotness at t_n from v_n = (v_{n-1/2} + v_{n+1/2}) / 2; at a mark, the stationarity stop
        if n_start <= step < n_end:
            if mark < marks.shape[0] and step == marks[mark]:
                if mark > 0:
                    if params.stop_tol > 0.0 and _stationary(hot1, hot2, counters[K_HALF1], counters[K_HALF2], kind,
                                                             gamma, params.stop_tol):
                        counters[K_STATIONARY] = step
                        break
                    for i in range(n):
                        hot1[i] += hot2[i]
                        hot2[i] = 0.0
                    counters[K_HALF1] += counters[K_HALF2]
                    counters[K_HALF2] = 0
                mark += 1
            counters[K_HOT_STEPS] += 1
            counters[K_HALF1 if mark == 0 else K_HALF2] += 1
            hot_sums(hot1 if mark == 0 else hot2, vm, vp)
        # --- drift to t_{n+1}: all particles (frozen ones have v = 0), then the driven ones by their fix
        for i in range(n):
            px[i], py[i], pz[i] = px[i] + dt * vpx[i], py[i] + dt * vpy[i], pz[i] + dt * vpz[i]
        drive_positions(t + dt, dt, moving, kind, x_rest, amp, phase, omega, vc, cpos, free_centre, pos)
        step += 1

    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
    e1 = kin = 0.0
    for i in range(n):  # after the loop vm = v_{n-1/2}, vp = v_{n+1/2} (no swap on exit)
        x[i, 0], x[i, 1], x[i, 2] = px[i], py[i], pz[i]
        e1 += vmx[i] * vpx[i] + vmy[i] * vpy[i] + vmz[i] * vpz[i]
        v0[i, 0], v0[i, 1], v0[i, 2] = 0.5 * (vmx[i] + vpx[i]), 0.5 * (vmy[i] + vpy[i]), 0.5 * (vmz[i] + vpz[i])
        kin += v0[i, 0] * v0[i, 0] + v0[i, 1] * v0[i, 1] + v0[i, 2] * v0[i, 2]
    q8 = 0.125 * mass * dt  # KE = m/2 |(vm + vp)/2|^2, times dt
    for i in range(n):
        hot[1, i], hot[2, i] = q8 * hot1[i], q8 * hot2[i]
        hot[0, i] = hot[1, i] + hot[2, i]
    pot = potential(px, py, pz, lattice, c, es)
    finish(counters, energy, step, status, half_m * e1 + pot, 0.5 * dt * sum8(dk), w_drive, w_bath, half_m * kin, pot)
    for k in range(lattice.pi.shape[0]):
        ever[k] = ever_s[lattice.slot[k]]
    return hrow


@njit(cache=True, boundscheck=False, error_model="numpy")
def run_p2(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int:
    """The kernel for the envelope (a/r)^2 (the vectorised pair loop); returns the history rows written."""
    return _run(state, lattice, fixes, params, out, True, potential_p2)


@njit(cache=True, boundscheck=False, error_model="numpy")
def run_any(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int:
    """The kernel for any envelope exponent p (x^-p through pow: correct, not vectorised)."""
    return _run(state, lattice, fixes, params, out, False, potential_any)
