"""Fast time-stepping kernels of the macromolecule model: the reference kernel's scheme, laid out for SIMD.

Same fixes, same kick-drift velocity Verlet with half-step (lagged) pair damping, same energy
identity and computes as `kernel_reference` (the plain kernel the tests compare against: equal to
rounding).  What differs is how the work is laid out:

- structure of arrays: positions, velocities and forces as separate x, y, z vectors;
- the pair list as a lattice stencil (`kernel_state.stencil`): groups of equal index offset o and
  rest shell, each one contiguous loop over the slots i = 0 .. N - o - 1 (pair (i, i + o)), with a
  0/1 mask for slots that are not listed pairs.  Contiguous loads let LLVM vectorise the loop;
  indices are unsigned (no numba wrap-around code);
- one loop per group computes the conservative force, the radial damping, the dissipation term and
  the hop flag, and adds the pair force to particle i in one accumulator and subtracts it from
  i + o in another (two arrays, so the loop carries no dependence and vectorises; their sum is the
  force).  The whole pair pass, every group loop included, is inlined into the step loop: a call
  per group costs numba's per-call set-up (reference counts of every array argument) and keeps LLVM
  from optimising across the groups;
- dissipation is exact every step and kept per slot: over n -> n+1 a slot dissipates
  1/2 dt (G_n . dv_{n+1/2} + delta rdot_{n+1}^2), G_n the slot's damping force of the previous pass,
  kept as one scalar q = g/r (G_n . dv = q d_n . dv, d_n = d_{n+1} - dt dv_{n+1/2}, so
  G_n . dv = q (r rdot - dt |dv|^2), exact to rounding).  The slot adds its term to its own running
  sum; the sums are added up (in 8 fixed partial sums, deterministic) only when a check records the
  history and at the end, not every step;
- the seven-root product as `force.force_tree` (no pow, exact near the roots), the envelope (a/r)^2
  as (a * (1/r))^2 (other exponents: pow), the STEP branch-free;
- hop detection stays exact in every pass: the group loop counts slots whose flag differs from the
  stored one (an integer reduction, vectorised), and the group's bookkeeping runs only then;
  NaN, box, energy-growth and neighbourhood checks run every `check_every` steps, as in the
  reference kernel; the potential energy they record is the reference's 12-point Gauss-Legendre
  rule vectorised over the slots;
- kick and drift run over all particles in one contiguous loop; held and bath particles are then
  overwritten by their own updates (index lists, no per-particle branches).

Variants, each compiled only when used (`kernels.KERNELS`): `run_p2` (envelope (a/r)^2, vectorised),
`run_any` (any exponent p) and `run_p2_fastmath` (run_p2 compiled with the FASTMATH flags).
"""

from __future__ import annotations

import math

import llvmlite.binding as llvm
import numpy as np
from numba import njit

from .codes import E_START, FREE, FROZEN, GROUP, K_HALF1, K_HALF2, K_HOT_STEPS, RUNNING
from .computes import finish, hop_out, neighbourhood, record, reset_outputs, verdict
from .force import _GL_W, _GL_X, C_A, C_P, C_ROOTS, C_X0, C_X1, energy_x, force_tree
from .kernel_state import FixArrays, LatticeArrays, RunOutputs, RunParams, RunState

__all__ = ["FASTMATH", "run_any", "run_p2", "run_p2_fastmath"]

# The group loop reads 16 and writes 8 arrays; LLVM's default limit on the runtime alias checks this
# needs ("too many memory checks needed") keeps it scalar.  Raising the limit only changes which loops
# get vectorised, never a result: no fastmath, no reassociation (the vectorised loops have no
# floating-point reductions), so vector and scalar code give the same bits.
llvm.set_option("", "-vectorize-memory-check-threshold=4096")

# The fastmath variant: FMA contraction, reciprocal and function approximations, no signed zeros.
# Not nnan/ninf: blow-ups are detected through NaN and inf, which those flags would let LLVM assume
# away.  The flags apply to the whole kernel (numba sets them per compiled function).  Tests hold it
# to the reference kernel's results to 1e-10.
FASTMATH = {"contract", "arcp", "afn", "nsz"}


@njit(inline="always")
def _slot(base, i, o):
    """Slot index of pair (i, i + o) in its group, and i and i + o: unsigned, so that numba emits
    no negative-index wrap-around (which hides the contiguous access from LLVM's vectoriser)."""
    return np.uint64(base + i), np.uint64(i), np.uint64(i + o)


@njit(inline="always")
def _group(pos, vel, o, base, lo, hi, mask, rt, shape, a, delta, dt, qk, dk, out, fi, fj, square):
    """One stencil group: pair forces added to fi[i] and subtracted from fj[i + o], each slot's
    dissipation term added to its running sum dk, the damping force over distance kept in qk; returns
    how many slots changed their hop flag (in or out of the root interval) against `out`.

    `square` is a constant (the envelope (a * (1/r))^2, vectorised, or x^-p through pow), so each
    compiled loop holds only its own envelope.  The loop body has no inner loop and no call (either
    keeps LLVM from vectorising it)."""
    px, py, pz = pos
    vx, vy, vz = vel
    fix, fiy, fiz = fi
    fjx, fjy, fjz = fj
    amp_a, p, step_lo, inv_w = shape
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
        dk[s] += qk[s] * (r * rdot - dt * (dvx * dvx + dvy * dvy + dvz * dvz)) + g * rdot
        qk[s] = g * ir
        f += g
        tx = f * ex
        ty = f * ey
        tz = f * ez
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
def _reduced(px, py, pz, i, j, inv_a):
    """Reduced distance |x_j - x_i| / a (the scalar loops' form of the vectorised loops' x)."""
    dx = px[j] - px[i]
    dy = py[j] - py[i]
    dz = pz[j] - pz[i]
    return math.sqrt(dx * dx + dy * dy + dz * dz) * inv_a


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


@njit(inline="always")
def _pair_pass(pos, vel, lattice, rt, shape, delta, dt, qk, dk, out, ever, step, counters, fi, fj, f, square):
    """Forces at the current positions (damping with the given velocities) into f = fi + fj; each slot's
    dissipation term over the interval ending here added to dk; hop flags exact, every slot, every pass."""
    fix, fiy, fiz = fi
    fjx, fjy, fjz = fj
    fx, fy, fz = f
    px, py, pz = pos
    for i in range(fx.shape[0]):
        fix[i] = 0.0
        fiy[i] = 0.0
        fiz[i] = 0.0
        fjx[i] = 0.0
        fjy[i] = 0.0
        fjz[i] = 0.0
    g_off, g_base, g_lo, g_hi, mask, a = lattice.g_off, lattice.g_base, lattice.g_lo, lattice.g_hi, lattice.mask, \
        lattice.a
    for g in range(g_off.shape[0]):
        changed = _group(pos, vel, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, rt, shape, a, delta, dt, qk, dk, out,
                         fi, fj, square)
        if changed != 0:
            _hops(px, py, pz, g_off[g], g_base[g], g_lo[g], g_hi[g], mask, a, out, ever, step, counters)
    for i in range(fx.shape[0]):
        fx[i] = fix[i] + fjx[i]
        fy[i] = fiy[i] + fjy[i]
        fz[i] = fiz[i] + fjz[i]


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


# Gauss-Legendre nodes of `force.energy_x` as symmetric pairs about the midpoint (node, weight): constant
# arrays and a loop of constant trip count, which LLVM unrolls, so that the slot loop of `_energy` vectorises
_GL_HALF_X = np.ascontiguousarray(_GL_X[6:])
_GL_HALF_W = np.ascontiguousarray(_GL_W[6:])
_STEP_END = 2.0  # where the STEP ends, in units of a (force.SevenRoot.coeffs: C_X1)


@njit(inline="always")
def _energy(px, py, pz, o, base, mask, r0s, rt, shape, a, es, square, in_step):
    """Per-slot potential energy U(r) - U(r0) of one group (over a), 12-point Gauss-Legendre.

    The same rule as `force.energy_x` (same nodes on [x0, x], the STEP's end 2a clamping both), vectorised
    over the slots.  energy_x splits an interval at the STEP's start, where F'' jumps; here a group
    integrates either below the start (in_step False: no STEP factor) or above it (in_step True: the
    STEP without its clamps), both constants.  A slot whose interval is not on the group's side gets 0
    and is counted; the caller evaluates those few with energy_x itself."""
    amp_a, p, step_lo, inv_w = shape
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    beyond = 0
    for i in range(px.shape[0] - o):
        s, iu, j = _slot(base, i, o)
        m = mask[s]
        dx, dy, dz = px[j] - px[iu], py[j] - py[iu], pz[j] - pz[iu]
        x = math.sqrt(dx * dx + dy * dy + dz * dz) * inv_a
        x0 = r0s[s] * inv_a
        if in_step:
            inside = (x > step_lo) & (x0 > step_lo)
            x = x if x < _STEP_END else _STEP_END
            x0 = x0 if x0 < _STEP_END else _STEP_END
        else:
            inside = (x <= step_lo) & (x0 <= step_lo)
        half = 0.5 * (x - x0)
        mid = 0.5 * (x + x0)
        acc = 0.0
        for k in range(6):  # the 12 nodes as 6 symmetric pairs
            xa = mid + half * _GL_HALF_X[k]
            xb = mid - half * _GL_HALF_X[k]
            fa = force_tree(xa, 1.0 / xa, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
            fb = force_tree(xb, 1.0 / xb, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
            if in_step:
                da = (xa - step_lo) * inv_w
                db = (xb - step_lo) * inv_w
                fa *= 1.0 - da * da * (3.0 - 2.0 * da)
                fb *= 1.0 - db * db * (3.0 - 2.0 * db)
            acc += _GL_HALF_W[k] * (fa + fb)
        es[s] = acc * half * m if inside else 0.0
        beyond += 1 if (m != 0.0) & (not inside) else 0
    return beyond


@njit(inline="always")
def _potential(px, py, pz, lattice, c, es, square):
    """U(x) - U(x_rest) summed over the listed pairs (J): `kernel_reference.potential_energy` on the stencil."""
    g_off, g_base, g_r0, mask, r0s, a = lattice.g_off, lattice.g_base, lattice.g_r0, lattice.mask, lattice.r0s, \
        lattice.a
    rt = c[C_ROOTS:C_ROOTS + 7]
    shape = (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]))
    inv_a = 1.0 / a
    for g in range(g_off.shape[0]):
        o = g_off[g]
        base = g_base[g]
        if g_r0[g] * inv_a > c[C_X0]:
            beyond = _energy(px, py, pz, o, base, mask, r0s, rt, shape, a, es, square, True)
        else:
            beyond = _energy(px, py, pz, o, base, mask, r0s, rt, shape, a, es, square, False)
        if beyond == 0:
            continue
        for i in range(px.shape[0] - o):
            s = base + i
            if mask[s] == 0.0:
                continue
            x = _reduced(px, py, pz, i, i + o, inv_a)
            x0 = r0s[s] * inv_a
            if (x > c[C_X0]) != (g_r0[g] * inv_a > c[C_X0]) or (x0 > c[C_X0]) != (g_r0[g] * inv_a > c[C_X0]):
                es[s] = energy_x(x0, x, c)
    return a * _sum8(es)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _potential_p2(px, py, pz, lattice, c, es):
    """`_potential` for the envelope (a/r)^2 (the vectorised loop)."""
    return _potential(px, py, pz, lattice, c, es, True)


@njit(cache=True, boundscheck=False, error_model="numpy")
def _potential_any(px, py, pz, lattice, c, es):
    """`_potential` for any envelope exponent p."""
    return _potential(px, py, pz, lattice, c, es, False)


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
    the group's centre velocity (added after); a step multiplies by 1/dt and adds it (the two
    roundings the reference kernel uses)."""
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


@njit(inline="always")
def _held_kick(t_next, t_now, dt, kind, held, amp, phase, omega, mass, f, vm, vp, lam, vc, group_mass, free_centre):
    """v_{n+1/2} of the held particles (prescribed, group) and lambda_n = m (vp - vm)/dt - F_n."""
    fx, fy, fz = f
    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
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


@njit(inline="always")
def _bath_kick(dt, bath, gamma, kt, mass, f, vm, vp, lam):
    """Langevin particles: exact OU factor with seeded noise, then the kick; lambda as for held ones."""
    fx, fy, fz = f
    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
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
def _start(v0, f, vm, kind, held, free, amp, phase, omega, dt, dtm, vc, group_mass, free_centre):
    """v_{-1/2} from v0 and the forces at t = 0, so that v_{+1/2} = v0 + dt/2 a0 (held particles: their
    motion over [-dt, 0]; the group's centre velocity from the forces on the group)."""
    fx, fy, fz = f
    vmx, vmy, vmz = vm
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


@njit(inline="always")
def _work(idx, v, lam0, lam1):
    """sum over idx of v . (lambda_prev + lambda_now) (times dt/2: the work over one interval)."""
    vx, vy, vz = v
    w = 0.0
    for q in range(idx.shape[0]):
        i = idx[q]
        w += vx[i] * (lam0[q, 0] + lam1[q, 0]) + vy[i] * (lam0[q, 1] + lam1[q, 1]) + vz[i] * (lam0[q, 2] + lam1[q, 2])
    return w


@njit(cache=True)
def _xyz(n):
    """x, y and z vectors of length n, zero (structure of arrays: three separate allocations)."""
    return np.zeros(n), np.zeros(n), np.zeros(n)


@njit(inline="always")
def _run(state, lattice, fixes, params, out, square, potential):
    """The kernel body: `kernel_reference.run`'s scheme and outputs on the stencil layout.  `square` (a
    constant) picks the envelope, `potential` the matching potential-energy function."""
    x, v0 = state
    x_rest, mass = lattice.x_rest, lattice.mass
    kind, amp, phase, gamma, kt, omega, free_centre, seed = fixes
    c, delta, dt, n_steps, n_start, n_end = params.coeffs, params.delta, params.dt, params.n_steps, params.n_start, \
        params.n_end
    hot, energy, counters, history, ever = out
    np.random.seed(seed)  # noqa: NPY002 (numba supports only the legacy seeded RNG in kernels)
    n = x.shape[0]
    npair = lattice.pi.shape[0]
    px = np.ascontiguousarray(x[:, 0])
    py = np.ascontiguousarray(x[:, 1])
    pz = np.ascontiguousarray(x[:, 2])
    pos = (px, py, pz)
    rt = c[C_ROOTS:C_ROOTS + 7].copy()
    shape = (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]))
    held = np.flatnonzero(kind != FREE)
    free = np.flatnonzero(kind == FREE)
    bath = np.flatnonzero((kind == FREE) & (gamma > 0.0))
    moving = np.flatnonzero((kind != FREE) & (kind != FROZEN))
    group_mass = mass * np.sum(kind == GROUP)
    if group_mass == 0.0:
        free_centre = False
    f = _xyz(n)
    fi = _xyz(n)
    fj = _xyz(n)
    fx, fy, fz = f
    vm = _xyz(n)
    vp = _xyz(n)
    ns = lattice.mask.shape[0]
    qk = np.zeros(ns)
    dk = np.zeros(ns)
    es = np.zeros(ns)
    ever_s = np.zeros(ns, dtype=np.int8)
    out_s = np.zeros(ns, dtype=np.int8)
    lh0 = np.zeros((held.shape[0], 3))
    lh1 = np.zeros((held.shape[0], 3))
    lb0 = np.zeros((bath.shape[0], 3))
    lb1 = np.zeros((bath.shape[0], 3))
    vc = np.zeros(3)
    cpos = np.zeros(3)
    hot1 = np.zeros(n)
    hot2 = np.zeros(n)
    reset_outputs(counters, energy)
    n_mid = (n_start + n_end) // 2
    half_m = 0.5 * mass
    dtm = dt / mass

    vpx, vpy, vpz = vp
    for i in range(n):
        vpx[i] = v0[i, 0]
        vpy[i] = v0[i, 1]
        vpz[i] = v0[i, 2]
    w_drive = w_bath = 0.0  # work done by drives and baths so far
    hrow = step = 0
    status = RUNNING
    while True:
        # --- forces at t_n with damping from v_{n-1/2} (at the start: v0); dissipation over n-1 -> n into dk.
        # One call site for every pass, so that the pair loops are compiled once
        _pair_pass(pos, vp, lattice, rt, shape, delta, dt, qk, dk, out_s, ever_s, step, counters, fi, fj, f,
                   square)
        if step == 0:
            _start(v0, f, vm, kind, held, free, amp, phase, omega, dt, dtm, vc, group_mass, free_centre)
            dk[:] = 0.0  # dissipation counts from the first interval on
        else:
            vm, vp = vp, vm  # v_{n-1/2} was the velocity of the drift
        vmx, vmy, vmz = vm
        vpx, vpy, vpz = vp
        t = step * dt
        # --- kick: v_{n+1/2} from v_{n-1/2} and F_n, over all particles (one contiguous, vectorised
        # loop); held and bath particles are then overwritten by their own kicks
        for i in range(n):
            vpx[i] = vmx[i] + dtm * fx[i]
            vpy[i] = vmy[i] + dtm * fy[i]
            vpz[i] = vmz[i] + dtm * fz[i]
        _held_kick(t + dt, t, dt, kind, held, amp, phase, omega, mass, f, vm, vp, lh1, vc, group_mass, free_centre)
        _bath_kick(dt, bath, gamma, kt, mass, f, vm, vp, lb1)
        if step == 0:
            e0 = 0.0
            for i in range(n):
                e0 += vmx[i] * vpx[i] + vmy[i] * vpy[i] + vmz[i] * vpz[i]
            energy[E_START] = half_m * e0 + potential(px, py, pz, lattice, c, es)
        else:
            # drive and bath work over n-1 -> n with v_{n-1/2}
            w_drive += 0.5 * dt * _work(held, vm, lh0, lh1)
            w_bath += 0.5 * dt * _work(bath, vm, lb0, lb1)
        lh0, lh1 = lh1, lh0
        lb0, lb1 = lb1, lb0
        if step == n_steps:
            break
        # --- checks at t_n (every check_every steps)
        if step % params.check_every == 0:
            kin = 0.0
            bad = False
            left = False
            box_lo, box_hi = params.box_lo, params.box_hi
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
            status = verdict(bad, left, kin, energy[E_START] + w_drive + w_bath, params.blowup_factor, params.e_scale)
            if status == RUNNING:
                status = neighbourhood(px, py, pz, x_rest, kind, lattice.pi, lattice.pj, lattice.a,
                                       params.cutoff_rest, params.contact_fraction, params.skin)
            if hrow < history.shape[0]:
                pot = potential(px, py, pz, lattice, c, es) if not bad else np.nan
                record(history, hrow, t, kin, pot, 0.5 * dt * _sum8(dk), w_drive, w_bath)
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
        step += 1

    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
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
        v0[i, 0] = ux  # the final velocities v_n, written over the initial ones
        v0[i, 1] = uy
        v0[i, 2] = uz
    q8 = 0.125 * mass * dt  # KE = m/2 |(vm + vp)/2|^2, times dt
    for i in range(n):
        hot[1, i] = q8 * hot1[i]
        hot[2, i] = q8 * hot2[i]
        hot[0, i] = hot[1, i] + hot[2, i]
    pot = potential(px, py, pz, lattice, c, es)
    finish(counters, energy, step, status, half_m * e1 + pot, 0.5 * dt * _sum8(dk), w_drive, w_bath, half_m * kin,
           pot)
    for k in range(npair):
        ever[k] = ever_s[lattice.slot[k]]
    return hrow


@njit(cache=True, boundscheck=False, error_model="numpy")
def run_p2(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int:
    """The fast kernel for the envelope (a/r)^2 (the vectorised pair loop)."""
    return _run(state, lattice, fixes, params, out, True, _potential_p2)


@njit(cache=True, boundscheck=False, error_model="numpy")
def run_any(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int:
    """The fast kernel for any envelope exponent p (x^-p through pow: correct, not vectorised)."""
    return _run(state, lattice, fixes, params, out, False, _potential_any)


@njit(cache=True, boundscheck=False, error_model="numpy", fastmath=FASTMATH)
def run_p2_fastmath(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams,
                    out: RunOutputs) -> int:
    """`run_p2` compiled with the FASTMATH flags."""
    return _run(state, lattice, fixes, params, out, True, _potential_p2)
