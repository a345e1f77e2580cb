"""Fast time-stepping kernel of the macromolecule model: `integrate.run`'s scheme, laid out for SIMD.

Same fixes, same kick-drift velocity Verlet with half-step (lagged) pair damping, same energy
identity and computes (see `integrate`'s docstring); `integrate.run` stays as the plain reference
kernel that the tests and the benchmark compare against (equal to rounding, no fastmath anywhere).
What differs is only how the work is laid out:

- structure of arrays: positions, velocities and forces as separate x, y, z vectors;
- pairs ordered for locality as a lattice stencil (`stencil`): the fixed pair list is grouped by
  index offset o = j - i (and rest shell), and each group is one contiguous loop over the slots
  i = 0 .. N - o - 1, with a 0/1 mask for slots that are not listed pairs (lattice edges: 29 %
  extra slots at N = 160).  Contiguous loads let LLVM vectorise the pair loop (it will not
  vectorise gathers through an index list on this CPU); the forces are added to i and subtracted
  from i + o in two more contiguous loops.  Indices are unsigned (no numba wrap-around code);
- one loop per group computes the conservative force, the radial damping, the per-slot
  dissipation term and the hop flag.  Dissipation over n -> n+1 is
  1/2 dt sum_k (G_k^n . (v_j - v_i)_{n+1/2} + delta rdot_k^2), with G_k^n the slot's damping
  force from the previous pass, kept as one scalar q = g/r per slot (G^n . dv = q d_n . dv and
  d_n = d_{n+1} - dt dv_{n+1/2}, exact to rounding), summed in 8 fixed partial sums;
- the seven-root product as a depth-3 tree of the root factors: no pow, exact near the roots.
  Horner in powers of x cancels catastrophically near the roots (6e-7 relative error of the force
  at x = sqrt3 + 1e-4, where the lattice lives), so it is not used; Horner about each pair's own
  root is accurate but needs per-shell coefficients and a 7-deep multiply-add chain.  The
  envelope (a/r)^2 is (a * (1/r))^2 (other exponents: pow, a scalar loop);
- the STEP is branch-free (clamped), so 2a pairs that cross 2a cost no branch mispredictions;
- hop detection stays exact in every pass: the group loop counts slots whose flag differs from
  the stored one (an integer reduction, vectorised), and the group's bookkeeping runs only then;
  NaN, box, energy-growth and neighbourhood checks run every `check_every` steps, as in the
  reference kernel; the potential energy they record is `potential`, the reference's 12-point
  Gauss-Legendre rule vectorised over the stencil slots (3x faster than the pair-list loop);
- kick and drift run over all particles in one contiguous loop; held and bath particles are then
  overwritten by their own updates (index lists, no per-particle branches).

Measured (tests/bench/test_bench_macromolecule.py, CPU time, N = 160, damping on, machine shared
with other jobs): ~8 ns per pair-step for the whole kernel against ~16 for the reference kernel
(ratio ~2 in one run).  The 3 ns target is not reached: on this CPU (Zen 4, AVX-512) the group
loop stripped to the slot forces (no dissipation terms, hop flags, scatter or integration) costs
2.6-2.9 ns per listed pair for the conservative force alone and 3.2-3.4 ns with the radial damping,
against 7.5-7.8 for the full pair pass (test_bench_kernel_floor, side by side; 29 % of the slots
are masked lattice-edge slots at N = 160).
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numpy as np
from numba import literal_unroll, njit

from .force import _GL_W, _GL_X, C_A, C_P, C_ROOTS, C_X0, C_X1, energy_x, force_tree
from .kernel_reference import (
    E_START,
    FREE,
    FROZEN,
    GROUP,
    K_HALF1,
    K_HALF2,
    K_HOT_STEPS,
    RUNNING,
    finish,
    hop_out,
    neighbourhood,
    record,
    reset_outputs,
    verdict,
)

__all__ = ["pair_pass", "run", "stencil"]

# The stencil loop reads 10 and writes 8 arrays; LLVM's default limit on the runtime alias checks
# this needs (128 pointer comparisons, "too many memory checks needed") keeps it scalar.  Raising
# the limit only changes which loops get vectorised, never a result: no fastmath, no reassociation
# (the loops have no floating-point reductions), so vector and scalar code give the same bits.
llvm.set_option("", "-vectorize-memory-check-threshold=4096")


def stencil(pairs: np.ndarray, shell: np.ndarray, n: int, basins: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pair list as groups of equal index offset o = j - i and rest shell (a lattice stencil).

    Group g covers the slots i = 0 .. n - o - 1 (pair (i, i + o)) at slots base_g + i, so every
    access in the pair loop is contiguous and the loop vectorises; slots that are not listed
    pairs (lattice edges) have mask 0 and contribute exactly nothing.  Returns (offset, base, lo,
    hi) per group, the slot mask and each listed pair's slot.
    """
    off = pairs[:, 1] - pairs[:, 0]
    key = off * 4 + shell
    keys, gidx = np.unique(key, return_inverse=True)
    g_off = (keys // 4).astype(np.int64)
    g_sh = keys % 4
    base = np.concatenate([[0], np.cumsum(n - g_off)]).astype(np.int64)
    slot = (base[gidx] + pairs[:, 0]).astype(np.int64)
    mask = np.zeros(base[-1])
    mask[slot] = 1.0
    lo = np.ascontiguousarray(basins[g_sh, 0])
    hi = np.ascontiguousarray(basins[g_sh, 1])
    return g_off, base, lo, hi, mask, slot


@njit(inline="always")
def _slot(base, i, o):
    """Slot index of pair (i, i + o) in its group, and i and i + o: unsigned, so that numba emits
    no negative-index wrap-around (which hides the contiguous access from LLVM's vectoriser)."""
    return np.uint64(base + i), np.uint64(i), np.uint64(i + o)


@njit(inline="always")
def _group(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
           qk, fsx, fsy, fsz, dk, out, square):
    """One stencil group: per-slot force vectors and dissipation terms in one loop; returns how
    many slots changed their hop flag (in or out of the root interval) against `out`.

    The damping force of the previous pass, G = g e, is kept as one scalar per slot, q = g / r:
    its work G . dv_{n+1/2} is q (d_n . dv), and d_n = d_{n+1} - dt dv_{n+1/2} because every
    particle moved by dt v_{n+1/2} (free ones drift so, held ones have v_{n+1/2} defined as their
    displacement over dt): exact to rounding, one stream per slot instead of three.

    Inlined at Numba IR level into `_group_p2` and `_group_any`, each passing `square` as a
    constant, so each compiled loop holds only its own envelope: (a * (1/r))^2, vectorised, or
    x^-p through pow (correct, not vectorised).  Indices are unsigned so that numba emits no
    negative-index wrap-around (which hides the contiguous access from LLVM's vectoriser), and the
    loop body has no inner loop and no call (either keeps LLVM from vectorising it)."""
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    changed = 0
    for i in range(px.shape[0] - o):
        s, iu, j = _slot(base, i, o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        ir = 1.0 / r
        ex = dx * ir
        ey = dy * ir
        ez = dz * ir
        x = r * inv_a
        f = force_tree(x, a * ir, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square) * m
        dvx = vx[j] - vx[iu]
        dvy = vy[j] - vy[iu]
        dvz = vz[j] - vz[iu]
        rdot = dvx * ex + dvy * ey + dvz * ez
        g = delta * rdot * m
        back = (dx * dvx + dy * dvy + dz * dvz) - dt * (dvx * dvx + dvy * dvy + dvz * dvz)
        dk[s] = qk[s] * back + g * rdot
        qk[s] = g * ir
        f += g
        fsx[s] = f * ex
        fsy[s] = f * ey
        fsz[s] = f * ez
        flag = np.int8(1) if ((x < lo) | (x >= hi)) & (m != 0.0) else np.int8(0)
        changed += flag != out[s]
    return changed


@njit(cache=True, boundscheck=False, error_model="numpy")
def _group_p2(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
              qk, fsx, fsy, fsz, dk, out):
    """`_group` for the default envelope (a/r)^2 (the vectorised loop)."""
    return _group(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
                  qk, fsx, fsy, fsz, dk, out, True)


# The fastmath variant: FMA contraction, reciprocal and function approximations, no signed zeros.
# Not nnan/ninf: blow-ups are detected through NaN and inf, which those flags would let LLVM assume
# away.  Used only by kernel "fastmath"; tests hold it to the exact kernel's results to 1e-10.
FASTMATH = {"contract", "arcp", "afn", "nsz"}


@njit(cache=True, boundscheck=False, error_model="numpy", fastmath=FASTMATH)
def _group_p2_fm(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
                 qk, fsx, fsy, fsz, dk, out):
    """`_group_p2` compiled with the FASTMATH flags."""
    return _group(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
                  qk, fsx, fsy, fsz, dk, out, True)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _group_any(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
              qk, fsx, fsy, fsz, dk, out):
    """`_group` for any envelope exponent p (x^-p through pow: correct, not vectorised)."""
    return _group(px, py, pz, vx, vy, vz, o, base, lo, hi, mask, rt, amp_a, p, step_lo, inv_w, a, delta, dt,
                  qk, fsx, fsy, fsz, dk, out, False)


@njit(cache=True, boundscheck=False)
def _scatter(o, base, fsx, fsy, fsz, fx, fy, fz):
    """Add the group's slot forces to i and subtract them from i + o (two contiguous loops)."""
    n = fx.shape[0]
    for i in range(n - o):
        s = np.uint64(base + i)
        iu = np.uint64(i)
        fx[iu] += fsx[s]
        fy[iu] += fsy[s]
        fz[iu] += fsz[s]
    for i in range(n - o):
        s = np.uint64(base + i)
        j = np.uint64(i + o)
        fx[j] -= fsx[s]
        fy[j] -= fsy[s]
        fz[j] -= fsz[s]


# Gauss-Legendre nodes of `seven_root.energy_x` as (node, weight) pairs about the midpoint: a tuple of
# constants that numba unrolls, so that the slot loop of `_energy` vectorises
_GL_PAIRS = tuple((float(x), float(w)) for x, w in zip(_GL_X[6:], _GL_W[6:], strict=True))


@njit(inline="always")
def _energy(px, py, pz, o, base, mask, r0s, rt, amp_a, p, step_lo, inv_w, a, es, square):
    """Per-slot potential energy U(r) - U(r0) of one group (over a), 12-point Gauss-Legendre.

    The same rule as `seven_root.energy_x` (same nodes on [x0, x]), vectorised over the slots: a
    slot whose x or x0 lies beyond the STEP start (where energy_x splits the interval) gets 0 here
    and is counted; the caller evaluates those few with energy_x itself."""
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    beyond = 0
    for i in range(px.shape[0] - o):
        s, iu, j = _slot(base, i, o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        x = math.sqrt(dx * dx + dy * dy + dz * dz) * inv_a
        x0 = r0s[s] * inv_a
        inside = (x <= step_lo) & (x0 <= step_lo)
        half = 0.5 * (x - x0)
        mid = 0.5 * (x + x0)
        acc = 0.0
        for k in literal_unroll(_GL_PAIRS):  # the 12 nodes as 6 symmetric pairs, unrolled
            xa = mid + half * k[0]
            xb = mid - half * k[0]
            fa = force_tree(xa, 1.0 / xa, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
            fb = force_tree(xb, 1.0 / xb, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
            acc += k[1] * (fa + fb)
        es[s] = acc * half * m if inside else 0.0
        beyond += 1 if (m != 0.0) & (not inside) else 0
    return beyond


@njit(cache=True, boundscheck=False, error_model="numpy")
def _energy_p2(px, py, pz, o, base, mask, r0s, rt, amp_a, p, step_lo, inv_w, a, es):
    """`_energy` for the default envelope (a/r)^2 (the vectorised loop)."""
    return _energy(px, py, pz, o, base, mask, r0s, rt, amp_a, p, step_lo, inv_w, a, es, True)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _energy_any(px, py, pz, o, base, mask, r0s, rt, amp_a, p, step_lo, inv_w, a, es):
    """`_energy` for any envelope exponent p."""
    return _energy(px, py, pz, o, base, mask, r0s, rt, amp_a, p, step_lo, inv_w, a, es, False)


@njit(inline="always")
def _reduced(px, py, pz, i, j, inv_a):
    """Reduced distance |x_j - x_i| / a (the scalar loops' form of the vectorised loops' x)."""
    dx = px[j] - px[i]
    dy = py[j] - py[i]
    dz = pz[j] - pz[i]
    return math.sqrt(dx * dx + dy * dy + dz * dz) * inv_a


@njit(cache=True, boundscheck=False)
def potential(px, py, pz, g_off, g_base, mask, r0s, c, pint, a, es):
    """U(x) - U(x_rest) summed over the listed pairs (J): `integrate.potential_energy` on the stencil."""
    rt = c[C_ROOTS:C_ROOTS + 7]
    inv_a = 1.0 / a
    inv_w = 1.0 / (c[C_X1] - c[C_X0])
    for g in range(g_off.shape[0]):
        o = g_off[g]
        base = g_base[g]
        if pint == 2:
            beyond = _energy_p2(px, py, pz, o, base, mask, r0s, rt, c[C_A], c[C_P], c[C_X0], inv_w, a, es)
        else:
            beyond = _energy_any(px, py, pz, o, base, mask, r0s, rt, c[C_A], c[C_P], c[C_X0], inv_w, a, es)
        if beyond == 0:
            continue
        for i in range(px.shape[0] - o):
            s = base + i
            if mask[s] == 0.0:
                continue
            x = _reduced(px, py, pz, i, i + o, inv_a)
            x0 = r0s[s] * inv_a
            if x > c[C_X0] or x0 > c[C_X0]:
                es[s] = energy_x(x0, x, c)
    return a * _sum8(es)


@njit(cache=True, boundscheck=False)
def _hops(px, py, pz, o, base, lo, hi, mask, a, out, ever, step, counters):
    """Hop bookkeeping of one group whose flags changed (rare): the flags again, slot by slot."""
    inv_a = 1.0 / a
    for i in range(px.shape[0] - o):
        s = base + i
        if mask[s] == 0.0:
            continue
        x = _reduced(px, py, pz, i, i + o, inv_a)
        if (x < lo) | (x >= hi):
            hop_out(s, out, ever, step, counters)
        elif out[s] != 0:
            out[s] = 0


@njit(cache=True, boundscheck=False)
def _sum8(v):
    """Sum in 8 fixed partial sums (one SIMD register): deterministic, and not a serial chain."""
    s0 = s1 = s2 = s3 = s4 = s5 = s6 = s7 = 0.0
    m = v.shape[0] - v.shape[0] % 8
    for k in range(0, m, 8):
        s0 += v[k]
        s1 += v[k + 1]
        s2 += v[k + 2]
        s3 += v[k + 3]
        s4 += v[k + 4]
        s5 += v[k + 5]
        s6 += v[k + 6]
        s7 += v[k + 7]
    for k in range(m, v.shape[0]):
        s0 += v[k]
    return ((s0 + s1) + (s2 + s3)) + ((s4 + s5) + (s6 + s7))


@njit(cache=True, boundscheck=False)
def pair_pass(px, py, pz, vx, vy, vz, g_off, g_base, g_lo, g_hi, mask, rt, amp_a, pint, p, step_lo, inv_w, a,
              delta, dt, qk, fsx, fsy, fsz, dk, out, ever, step, counters, fx, fy, fz, fm):
    """Forces at the current positions (damping with the given velocities) into fx, fy, fz.

    Returns 1/2 sum_k (G_k^prev . dv_k + delta rdot_k^2) (times dt: dissipation over the interval
    ending here; summed in 8 fixed partial sums, so deterministic); qk holds each slot's damping
    force over distance for the next pass.  Hop flags are exact: every slot, every pass."""
    n = px.shape[0]
    for i in range(n):
        fx[i] = 0.0
        fy[i] = 0.0
        fz[i] = 0.0
    for g in range(g_off.shape[0]):
        if pint == 2 and fm:
            changed = _group_p2_fm(px, py, pz, vx, vy, vz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, rt, amp_a,
                                   p, step_lo, inv_w, a, delta, dt, qk, fsx, fsy, fsz, dk, out)
        elif pint == 2:
            changed = _group_p2(px, py, pz, vx, vy, vz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, rt, amp_a, p,
                                step_lo, inv_w, a, delta, dt, qk, fsx, fsy, fsz, dk, out)
        else:
            changed = _group_any(px, py, pz, vx, vy, vz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, rt, amp_a, p,
                                 step_lo, inv_w, a, delta, dt, qk, fsx, fsy, fsz, dk, out)
        if changed != 0:
            _hops(px, py, pz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, a, out, ever, step, counters)
        _scatter(g_off[g], g_base[g], fsx, fsy, fsz, fx, fy, fz)
    return 0.5 * _sum8(dk)


@njit(inline="always")
def _group_force(kind, held, fx, fy, fz):
    """Sum of the forces on the group particles (in index order)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    for q in range(held.shape[0]):
        i = held[q]
        if kind[i] == GROUP:
            s0 += fx[i]
            s1 += fy[i]
            s2 += fz[i]
    return s0, s1, s2


@njit(inline="always")
def _held_velocity(t_next, t_now, dt, kind, held, amp, phase, omega, vc, vx, vy, vz, start):
    """Velocity of the held particles over [t_now, t_next] into vx, vy, vz (0 for frozen ones).

    `start` is a constant: v_{-1/2} at the start divides the sine difference by dt and leaves out
    the group's centre velocity (added after); a step multiplies by 1/dt and adds it.  The two
    roundings are kept as they were, so that results stay bit-identical."""
    inv_dt = 1.0 / dt
    for q in range(held.shape[0]):
        i = held[q]
        if kind[i] == FROZEN:
            vx[i] = 0.0
            vy[i] = 0.0
            vz[i] = 0.0
        else:
            if start:
                ds = (math.sin(omega * t_next + phase[i]) - math.sin(omega * t_now + phase[i])) / dt
            else:
                ds = (math.sin(omega * t_next + phase[i]) - math.sin(omega * t_now + phase[i])) * inv_dt
            vx[i] = amp[i, 0] * ds
            vy[i] = amp[i, 1] * ds
            vz[i] = amp[i, 2] * ds
            if not start and kind[i] == GROUP:
                vx[i] += vc[0]
                vy[i] += vc[1]
                vz[i] += vc[2]


@njit(cache=True)
def _held_kick(t_next, t_now, dt, kind, held, amp, phase, omega, mass, fx, fy, fz, vmx, vmy, vmz,
               vpx, vpy, vpz, lam, vc, group_mass, free_centre):
    """v_{n+1/2} of the held particles (prescribed, group) and lambda_n = m (vp - vm)/dt - F_n."""
    if free_centre:
        s0, s1, s2 = _group_force(kind, held, fx, fy, fz)
        vc[0] += dt * s0 / group_mass
        vc[1] += dt * s1 / group_mass
        vc[2] += dt * s2 / group_mass
    _held_velocity(t_next, t_now, dt, kind, held, amp, phase, omega, vc, vpx, vpy, vpz, False)
    inv_dt = 1.0 / dt
    for q in range(held.shape[0]):
        i = held[q]
        lam[q, 0] = mass * (vpx[i] - vmx[i]) * inv_dt - fx[i]
        lam[q, 1] = mass * (vpy[i] - vmy[i]) * inv_dt - fy[i]
        lam[q, 2] = mass * (vpz[i] - vmz[i]) * inv_dt - fz[i]


@njit(cache=True)
def _bath_kick(dt, bath, gamma, kt, mass, fx, fy, fz, vmx, vmy, vmz, vpx, vpy, vpz, lam):
    """Langevin particles: exact OU factor with seeded noise, then the kick; lambda as for held ones."""
    inv_dt = 1.0 / dt
    for q in range(bath.shape[0]):
        i = bath[q]
        damp = math.exp(-gamma[i] * dt)
        sig = math.sqrt(kt[i] / mass * (1.0 - damp * damp))
        vpx[i] = vmx[i] * damp + sig * np.random.standard_normal() + dt * fx[i] / mass  # noqa: NPY002
        vpy[i] = vmy[i] * damp + sig * np.random.standard_normal() + dt * fy[i] / mass  # noqa: NPY002
        vpz[i] = vmz[i] * damp + sig * np.random.standard_normal() + dt * fz[i] / mass  # noqa: NPY002
        lam[q, 0] = mass * (vpx[i] - vmx[i]) * inv_dt - fx[i]
        lam[q, 1] = mass * (vpy[i] - vmy[i]) * inv_dt - fy[i]
        lam[q, 2] = mass * (vpz[i] - vmz[i]) * inv_dt - fz[i]


@njit(cache=True)
def _work(idx, vx, vy, vz, lam0, lam1):
    """sum over idx of v . (lambda_prev + lambda_now) (times dt/2: the work over one interval)."""
    w = 0.0
    for q in range(idx.shape[0]):
        i = idx[q]
        w += vx[i] * (lam0[q, 0] + lam1[q, 0]) + vy[i] * (lam0[q, 1] + lam1[q, 1]) + vz[i] * (lam0[q, 2] + lam1[q, 2])
    return w


@njit(inline="always")
def _xyz(n):
    """x, y and z vectors of length n, zero (structure of arrays: three separate allocations)."""
    return np.zeros(n), np.zeros(n), np.zeros(n)


@njit(cache=True)
def run(x, v0, x_rest, kind, amp, phase, omega, free_centre, mass, gamma, kt, seed,
        pi, pj, g_off, g_base, g_lo, g_hi, mask, slot, pint, a, delta, dt, n_steps, n_start, n_end,
        check_every, blowup_factor, e_scale, box_lo, box_hi, contact_fraction, cutoff_rest, skin, c,
        r0, hot, energy, counters, history, ever, fm):
    """Integrate n_steps from t = 0; same outputs and stopping rules as `integrate.run`.

    fm: the pair loop compiled with FASTMATH (envelope p = 2 only; other p use the exact loop).
    c = model.coeffs() (roots, A, p, STEP start); pint = p if p is a small integer else -1.
    x (N, 3) is overwritten with the final positions.
    """
    np.random.seed(seed)  # noqa: NPY002 (numba supports only the legacy seeded RNG in kernels)
    n = x.shape[0]
    npair = pi.shape[0]
    px = np.ascontiguousarray(x[:, 0])
    py = np.ascontiguousarray(x[:, 1])
    pz = np.ascontiguousarray(x[:, 2])
    rt = c[C_ROOTS:C_ROOTS + 7].copy()
    amp_a = c[C_A]
    p = c[C_P]
    step_lo = c[C_X0]
    inv_w = 1.0 / (c[C_X1] - step_lo)
    held = np.flatnonzero(kind != FREE)
    free = np.flatnonzero(kind == FREE)
    bath = np.flatnonzero((kind == FREE) & (gamma > 0.0))
    moving = np.flatnonzero((kind != FREE) & (kind != FROZEN))
    group_mass = mass * np.sum(kind == GROUP)
    if group_mass == 0.0:
        free_centre = False
    fx, fy, fz = _xyz(n)
    vmx, vmy, vmz = _xyz(n)
    vpx, vpy, vpz = _xyz(n)
    ns = mask.shape[0]
    qk = np.zeros(ns)
    es = np.zeros(ns)
    r0s = np.zeros(ns)
    for k in range(npair):
        r0s[slot[k]] = r0[k]
    fsx, fsy, fsz = _xyz(ns)
    dk = np.zeros(ns)
    ever_s = np.zeros(ns, dtype=np.int8)
    lh0 = np.zeros((held.shape[0], 3))
    lh1 = np.zeros((held.shape[0], 3))
    lb0 = np.zeros((bath.shape[0], 3))
    lb1 = np.zeros((bath.shape[0], 3))
    vc = np.zeros(3)
    cpos = np.zeros(3)
    out = np.zeros(ns, dtype=np.int8)
    hot1 = np.zeros(n)
    hot2 = np.zeros(n)
    reset_outputs(counters, energy)
    n_mid = (n_start + n_end) // 2
    half_m = 0.5 * mass
    dtm = dt / mass

    # start: forces at t = 0 with damping from v0; v_{-1/2} so that v_{+1/2} = v0 + dt/2 a0
    for i in range(n):
        vpx[i] = v0[i, 0]
        vpy[i] = v0[i, 1]
        vpz[i] = v0[i, 2]
    pair_pass(px, py, pz, vpx, vpy, vpz, g_off, g_base, g_lo, g_hi, mask, rt, amp_a, pint, p, step_lo, inv_w, a,
              delta, dt, qk, fsx, fsy, fsz, dk, out, ever_s, 0, counters, fx, fy, fz, fm)
    for q in range(free.shape[0]):
        i = free[q]
        vmx[i] = v0[i, 0] - 0.5 * dtm * fx[i]
        vmy[i] = v0[i, 1] - 0.5 * dtm * fy[i]
        vmz[i] = v0[i, 2] - 0.5 * dtm * fz[i]
    _held_velocity(0.0, -dt, dt, kind, held, amp, phase, omega, vc, vmx, vmy, vmz, True)
    if free_centre:
        s0, s1, s2 = _group_force(kind, held, fx, fy, fz)
        vc[0] = -0.5 * dt * s0 / group_mass
        vc[1] = -0.5 * dt * s1 / group_mass
        vc[2] = -0.5 * dt * s2 / group_mass
        for q in range(held.shape[0]):
            i = held[q]
            if kind[i] == GROUP:
                vmx[i] += vc[0]
                vmy[i] += vc[1]
                vmz[i] += vc[2]

    diss = w_drive = w_bath = 0.0  # energy dissipated and work done by drives and baths so far
    hrow = step = 0
    status = RUNNING
    while True:
        t = step * dt
        # --- kick: v_{n+1/2} from v_{n-1/2} and F_n, over all particles (one contiguous, vectorised
        # loop); held and bath particles are then overwritten by their own kicks
        for i in range(n):
            vpx[i] = vmx[i] + dtm * fx[i]
            vpy[i] = vmy[i] + dtm * fy[i]
            vpz[i] = vmz[i] + dtm * fz[i]
        _held_kick(t + dt, t, dt, kind, held, amp, phase, omega, mass, fx, fy, fz, vmx, vmy, vmz,
                   vpx, vpy, vpz, lh1, vc, group_mass, free_centre)
        _bath_kick(dt, bath, gamma, kt, mass, fx, fy, fz, vmx, vmy, vmz, vpx, vpy, vpz, lb1)
        if step == 0:
            e0 = 0.0
            for i in range(n):
                e0 += vmx[i] * vpx[i] + vmy[i] * vpy[i] + vmz[i] * vpz[i]
            energy[E_START] = half_m * e0 + potential(px, py, pz, g_off, g_base, mask, r0s, c, pint, a, es)
        else:
            # drive and bath work over n-1 -> n with v_{n-1/2}
            w_drive += 0.5 * dt * _work(held, vmx, vmy, vmz, lh0, lh1)
            w_bath += 0.5 * dt * _work(bath, vmx, vmy, vmz, lb0, lb1)
        lh0, lh1 = lh1, lh0
        lb0, lb1 = lb1, lb0
        if step == n_steps:
            break
        # --- checks at t_n (every check_every steps)
        if step % check_every == 0:
            kin = 0.0
            bad = False
            left = False
            for i in range(n):
                ux = 0.5 * (vmx[i] + vpx[i])
                uy = 0.5 * (vmy[i] + vpy[i])
                uz = 0.5 * (vmz[i] + vpz[i])
                kin += ux * ux + uy * uy + uz * uz
                if not (math.isfinite(px[i]) and math.isfinite(py[i]) and math.isfinite(pz[i])
                        and math.isfinite(ux) and math.isfinite(uy) and math.isfinite(uz)):
                    bad = True
                if (px[i] < box_lo[0] or px[i] > box_hi[0] or py[i] < box_lo[1] or py[i] > box_hi[1]
                        or pz[i] < box_lo[2] or pz[i] > box_hi[2]):
                    left = True
            kin *= half_m
            status = verdict(bad, left, kin, energy[E_START] + w_drive + w_bath, blowup_factor, e_scale)
            if status == RUNNING:
                status = neighbourhood(px, py, pz, x_rest, kind, pi, pj, a, cutoff_rest, contact_fraction, skin)
            if hrow < history.shape[0]:
                pot = potential(px, py, pz, g_off, g_base, mask, r0s, c, pint, a, es) if not bad else np.nan
                record(history, hrow, t, kin, pot, diss, w_drive, w_bath)
                hrow += 1
            if status != RUNNING:
                break
        # --- hotness at t_n from v_n = (v_{n-1/2} + v_{n+1/2}) / 2
        if n_start <= step < n_end:
            counters[K_HOT_STEPS] += 1
            acc = hot1 if step < n_mid else hot2
            counters[K_HALF1 if step < n_mid else K_HALF2] += 1
            for i in range(n):
                ux = vmx[i] + vpx[i]
                uy = vmy[i] + vpy[i]
                uz = vmz[i] + vpz[i]
                acc[i] += ux * ux + uy * uy + uz * uz
        # --- drift to t_{n+1}
        t1 = t + dt
        for i in range(n):  # all particles: frozen ones have v = 0, moving ones are set below
            px[i] += dt * vpx[i]
            py[i] += dt * vpy[i]
            pz[i] += dt * vpz[i]
        if free_centre:
            for d in range(3):
                cpos[d] += dt * vc[d]
        for q in range(moving.shape[0]):
            i = moving[q]
            s1 = math.sin(omega * t1 + phase[i])
            px[i] = x_rest[i, 0] + amp[i, 0] * s1
            py[i] = x_rest[i, 1] + amp[i, 1] * s1
            pz[i] = x_rest[i, 2] + amp[i, 2] * s1
            if kind[i] == GROUP:
                px[i] += cpos[0]
                py[i] += cpos[1]
                pz[i] += cpos[2]
        # --- forces at t_{n+1} with damping from v_{n+1/2}; dissipation over n -> n+1
        diss += dt * pair_pass(px, py, pz, vpx, vpy, vpz, g_off, g_base, g_lo, g_hi, mask, rt, amp_a, pint, p,
                               step_lo, inv_w, a, delta, dt, qk, fsx, fsy, fsz, dk, out, ever_s, step + 1,
                               counters, fx, fy, fz, fm)
        vmx, vmy, vmz, vpx, vpy, vpz = vpx, vpy, vpz, vmx, vmy, vmz  # v_{n+1/2} is v_{n-1/2} of the next step
        step += 1

    e1 = 0.0
    kin = 0.0
    for i in range(n):
        x[i, 0] = px[i]
        x[i, 1] = py[i]
        x[i, 2] = pz[i]
        # after the loop vm = v_{n-1/2}, vp = v_{n+1/2} (no swap on exit)
        e1 += vmx[i] * vpx[i] + vmy[i] * vpy[i] + vmz[i] * vpz[i]
        ux = 0.5 * (vmx[i] + vpx[i])
        uy = 0.5 * (vmy[i] + vpy[i])
        uz = 0.5 * (vmz[i] + vpz[i])
        kin += ux * ux + uy * uy + uz * uz
    q8 = 0.125 * mass * dt  # KE = m/2 |(vm + vp)/2|^2, times dt
    for i in range(n):
        hot[1, i] = q8 * hot1[i]
        hot[2, i] = q8 * hot2[i]
        hot[0, i] = hot[1, i] + hot[2, i]
    pot = potential(px, py, pz, g_off, g_base, mask, r0s, c, pint, a, es)
    finish(counters, energy, step, status, half_m * e1 + pot, diss, w_drive, w_bath, half_m * kin, pot)
    for k in range(npair):
        ever[k] = ever_s[slot[k]]
    return hrow
