"""Computes of the macromolecule kernel (LAMMPS' word for measurements), called from its step: hop events, the
state and neighbourhood checks, the potential energy, hotness sums, the energy history, the final counters."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from . import codes
from .force import _GL_W, _GL_X, C_A, C_P, C_ROOTS, C_X0, C_X1, energy_x, pair_force


@njit(inline="always")
def reduced(px, py, pz, i, j, inv_a):
    """Reduced distance |x_j - x_i| / a."""
    dx, dy, dz = px[j] - px[i], py[j] - py[i], pz[j] - pz[i]
    return math.sqrt(dx * dx + dy * dy + dz * dz) * inv_a


@njit(cache=True, boundscheck=False)
def hops(px, py, pz, o, base, lo, hi, mask, a, out, ever, step, counters):
    """Hop bookkeeping of one stencil group whose flags changed (rare), slot by slot: a slot outside its root
    interval is an event if it was inside, its pair's first exit counts it, the first one the step."""
    inv_a = 1.0 / a
    for i in range(px.shape[0] - o):
        s = base + i
        if mask[s] == 0.0:
            continue
        x = reduced(px, py, pz, i, i + o, inv_a)
        if (x < lo) | (x >= hi):
            if out[s] == 0:
                out[s] = 1
                counters[codes.K_HOP_EVENTS] += 1
                if ever[s] == 0:
                    ever[s] = 1
                    counters[codes.K_HOP_PAIRS] += 1
                    if counters[codes.K_FIRST_HOP] < 0:
                        counters[codes.K_FIRST_HOP] = step
        elif out[s] != 0:
            out[s] = 0


@njit(inline="always")
def check(pos, vm, vp, box_lo, box_hi, half_m, supplied, blowup_factor, e_scale):
    """(status, kinetic energy, NaN seen) at t_n from the state alone: NaN/inf, a particle outside the box,
    kinetic energy above blowup_factor times (the energy supplied plus e_scale), else RUNNING."""
    px, py, pz = pos
    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
    kin = 0.0
    bad = left = False
    for i in range(px.shape[0]):
        ux, uy, uz = 0.5 * (vmx[i] + vpx[i]), 0.5 * (vmy[i] + vpy[i]), 0.5 * (vmz[i] + vpz[i])
        kin += ux * ux + uy * uy + uz * uz
        if not (math.isfinite(px[i]) and math.isfinite(py[i]) and math.isfinite(pz[i])
                and math.isfinite(ux) and math.isfinite(uy) and math.isfinite(uz)):
            bad = True
        if (px[i] < box_lo[0] or px[i] > box_hi[0] or py[i] < box_lo[1] or py[i] > box_hi[1]
                or pz[i] < box_lo[2] or pz[i] > box_hi[2]):
            left = True
    kin *= half_m
    if bad:
        return codes.NAN, kin, bad
    if left:
        return codes.LEFT_BAR, kin, bad
    if kin > blowup_factor * (max(supplied, 0.0) + e_scale):
        return codes.GROWTH, kin, bad
    return codes.RUNNING, kin, bad


@njit(cache=True)
def neighbourhood(px, py, pz, x_rest, kind, pi, pj, a, cutoff_rest, contact_fraction, skin):
    """ISOLATED / CONTACT check of the fixed pair list (positions as x, y, z vectors); RUNNING if fine."""
    n = px.shape[0]
    near = np.full(n, np.inf)
    for k in range(pi.shape[0]):
        i, j = pi[k], pj[k]
        r = reduced(px, py, pz, i, j, 1.0)
        near[i] = min(near[i], r)
        near[j] = min(near[j], r)
    for i in range(n):
        if kind[i] != codes.FROZEN and near[i] > 2.0 * a:
            return codes.ISOLATED
    # unlisted pairs: only possible when some particle moved more than the skin
    dmax2 = 0.0
    for i in range(n):
        dmax2 = max(dmax2, (px[i] - x_rest[i, 0]) ** 2 + (py[i] - x_rest[i, 1]) ** 2 + (pz[i] - x_rest[i, 2]) ** 2)
    if 4.0 * dmax2 < skin * skin:
        return codes.RUNNING
    if unlisted_contact(px, py, pz, x_rest, contact_fraction * a, cutoff_rest * cutoff_rest):
        return codes.CONTACT
    return codes.RUNNING


@njit(cache=True, boundscheck=False)
def unlisted_contact(px, py, pz, x_rest, lim, cut2):
    """Whether two particles not listed as a pair (rest distance squared above cut2) are closer than lim.  A cell
    list of side h >= lim (doubled until there are at most 8 cells per particle): only particles in the same or
    adjacent cells can be that close, so the answer is the all-pairs search's in O(N) (counting sort by cell)."""
    n = px.shape[0]
    lo_x, lo_y, lo_z = px.min(), py.min(), pz.min()
    h = lim
    while True:
        nx, ny, nz = (int((px.max() - lo_x) / h) + 1, int((py.max() - lo_y) / h) + 1,
                      int((pz.max() - lo_z) / h) + 1)
        if nx * ny * nz <= 8 * n + 64:
            break
        h *= 2.0
    cell = np.empty(n, dtype=np.int64)
    start = np.zeros(nx * ny * nz + 1, dtype=np.int64)
    for i in range(n):
        cell[i] = (int((px[i] - lo_x) / h) * ny + int((py[i] - lo_y) / h)) * nz + int((pz[i] - lo_z) / h)
        start[cell[i] + 1] += 1
    for c in range(nx * ny * nz):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(n, dtype=np.int64)
    for i in range(n):
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    lim2 = lim * lim
    for i in range(n):
        cx, rest = divmod(cell[i], ny * nz)
        cy, cz = divmod(rest, nz)
        for ax in range(max(cx - 1, 0), min(cx + 2, nx)):
            for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
                for az in range(max(cz - 1, 0), min(cz + 2, nz)):
                    c = (ax * ny + ay) * nz + az
                    for k in range(start[c], start[c + 1]):
                        j = order[k]
                        if j <= i:
                            continue
                        d2 = (px[j] - px[i]) ** 2 + (py[j] - py[i]) ** 2 + (pz[j] - pz[i]) ** 2
                        if d2 < lim2:
                            rest2 = ((x_rest[j, 0] - x_rest[i, 0]) ** 2 + (x_rest[j, 1] - x_rest[i, 1]) ** 2
                                     + (x_rest[j, 2] - x_rest[i, 2]) ** 2)
                            if rest2 > cut2:
                                return True
    return False


@njit(cache=True, boundscheck=False)
def sum8(v):
    """Sum in 8 fixed partial sums (one SIMD register): deterministic, and not a serial chain."""
    s = np.zeros(8)
    m = v.shape[0] - v.shape[0] % 8
    for k in range(0, m, 8):
        for lane in range(8):
            s[lane] += v[k + lane]
    for k in range(m, v.shape[0]):
        s[0] += v[k]
    return ((s[0] + s[1]) + (s[2] + s[3])) + ((s[4] + s[5]) + (s[6] + s[7]))


# Gauss-Legendre nodes of `force.energy_x` as symmetric pairs about the midpoint (node, weight): constant
# arrays and a loop of constant trip count, which LLVM unrolls, so that the slot loop of `_energy` vectorises
_GL_HALF_X = np.ascontiguousarray(_GL_X[6:])
_GL_HALF_W = np.ascontiguousarray(_GL_W[6:])
_STEP_END = 2.0  # where the STEP ends, in units of a (force.SevenRoot.coeffs: C_X1)


@njit(inline="always")
def _energy(px, py, pz, o, base, mask, r0s, rt, shape, a, es, square, in_step):
    """Per-slot potential energy U(r) - U(r0) of one stencil group (over a): `force.energy_x`'s rule (12-point
    Gauss-Legendre on [x0, x], 2a clamping both) vectorised over the slots, either below the STEP's start
    (in_step False) or above it (True: the STEP without its clamps).  A slot whose interval is not on the
    group's side gets 0 and is counted; the caller evaluates those few with energy_x itself."""
    amp_a, p, step_lo, inv_w = shape
    inv_a = 1.0 / a
    r0, r1, r2, r3, r4, r5, r6 = rt[0], rt[1], rt[2], rt[3], rt[4], rt[5], rt[6]
    beyond = 0
    for i in range(px.shape[0] - o):
        s, iu, j = np.uint64(base + i), np.uint64(i), np.uint64(i + o)
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
            fa = pair_force(xa, 1.0 / xa, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
            fb = pair_force(xb, 1.0 / xb, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, False)
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
    """U(x) - U(x_rest) summed over the listed pairs (J), group by group on the stencil."""
    g_off, g_base, g_r0, mask, r0s, a = lattice.g_off, lattice.g_base, lattice.g_r0, lattice.mask, lattice.r0s, \
        lattice.a
    rt = c[C_ROOTS:C_ROOTS + 7]
    shape = (c[C_A], c[C_P], c[C_X0], 1.0 / (c[C_X1] - c[C_X0]))
    inv_a = 1.0 / a
    for g in range(g_off.shape[0]):
        o, base = g_off[g], g_base[g]
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
            x = reduced(px, py, pz, i, i + o, inv_a)
            x0 = r0s[s] * inv_a
            if (x > c[C_X0]) != (g_r0[g] * inv_a > c[C_X0]) or (x0 > c[C_X0]) != (g_r0[g] * inv_a > c[C_X0]):
                es[s] = energy_x(x0, x, c)
    return a * sum8(es)


@njit(cache=True, boundscheck=False, error_model="numpy")
def potential_p2(px, py, pz, lattice, c, es):
    """`_potential` for the envelope (a/r)^2 (the vectorised loop)."""
    return _potential(px, py, pz, lattice, c, es, True)


@njit(cache=True, boundscheck=False, error_model="numpy")
def potential_any(px, py, pz, lattice, c, es):
    """`_potential` for any envelope exponent p."""
    return _potential(px, py, pz, lattice, c, es, False)


@njit(inline="always")
def hot_sums(acc, vm, vp):
    """Add |v_{n-1/2} + v_{n+1/2}|^2 (4 |v_n|^2) of every particle to its hotness sum."""
    vmx, vmy, vmz = vm
    vpx, vpy, vpz = vp
    for i in range(acc.shape[0]):
        ux, uy, uz = vmx[i] + vpx[i], vmy[i] + vpy[i], vmz[i] + vpz[i]
        acc[i] += ux * ux + uy * uy + uz * uz


@njit(inline="always")
def record(history, hrow, t, kin, pot, diss, w_drive, w_bath):
    """One row of the coarse energy history."""
    history[hrow, codes.H_T], history[hrow, codes.H_KIN], history[hrow, codes.H_POT] = t, kin, pot
    history[hrow, codes.H_DISS], history[hrow, codes.H_DRIVE], history[hrow, codes.H_BATH] = diss, w_drive, w_bath


@njit(inline="always")
def finish(counters, energy, step, status, e_end, diss, w_drive, w_bath, kin_end, pot_end):
    """Counters and energies of a run that stopped at `step` with `status` (RUNNING: completed)."""
    counters[codes.K_STEPS] = counters[codes.K_STOP_STEP] = step
    counters[codes.K_STATUS] = codes.DONE if status == codes.RUNNING else status
    energy[codes.E_END], energy[codes.E_DISS], energy[codes.E_DRIVE] = e_end, diss, w_drive
    energy[codes.E_BATH], energy[codes.E_KIN_END], energy[codes.E_POT_END] = w_bath, kin_end, pot_end
