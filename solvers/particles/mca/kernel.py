"""Numba kernels of the MCA solver: pair and many-body forces in incremental form, velocity Verlet.

Pair state (per listed pair p = (i, j), n the unit vector from i to j, q = r0/2 on either side):
- normal stress sig (tension > 0) and tangential stress vector tau (in the pair's tangent plane), both
  "effective" (undamaged) stresses carried incrementally; the force on i is S (1 - d_ij) (sig n + tau),
  d_ij the mean damage of the two automata;
- linked (1) or unlinked (0).  Unlinked pairs carry compression only, sig = kc min(0, (r - r0)/r0), and
  Coulomb friction |tau| <= mu |sig|.
Increments over one step (strain split: equal automata, so q_ij = q_ji = r0/2 and equal stresses give
equal pair strains on both sides, see mca.py for the derivation of the many-body coefficient):
    d sig = kn d r / r0 + lam (d theta_i + d theta_j) / 2,
    d tau = (2 G / r0) d delta_t,   d delta = d x_j - d x_i - q (d phi_i + d phi_j) x n  (contact points),
theta_i = sum_j S_ij (r_ij - r0_ij) / (2 Omega_i) is the automaton's volume strain from the displacements
of its contact points (eq. 9 of PHYSICS.md §4); kn = 2G and lam = 1 - 2G/(3K) times K with the many-body
term, kn = E and lam = 0 without it (pair-only).  tau is carried to the new tangent plane each step
(projection, magnitude kept).
Automaton state: average stress (from the pair stresses, sigma = (1/Omega) sum q S (sig n n + sym(n tau))),
equivalent plastic strain alpha (radial return), kappa (largest effective stress intensity) and damage d.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

# float parameters (fp)
F_DT, F_G, F_LAM, F_KN, F_KC, F_MU, F_GAMMA, F_T, F_TSTOP, F_SKIN, F_KEMAX = range(11)
F_SC, F_KDP, F_SY, F_HP, F_SD, F_HDE, F_KROT, F_RELINK = range(11, 19)
N_FP = 19
# int parameters (ip)
I_KIND, I_FRACTURE, I_ROT, I_RELINK, I_REC = range(5)
N_IP = 5
# counters
C_STEPS, C_STATUS, C_UNLINK, C_RELINK, C_PAIRSTEPS, C_ROWS = range(6)
N_C = 6
# energy accumulators
E_WORK, E_DISS = range(2)
# status codes
OK, NAN, GROWTH, MOVED = 0, 1, 2, 3
STATUS_TEXT = {OK: "ok", NAN: "non-finite state", GROWTH: "kinetic energy above the blow-up limit",
               MOVED: "an automaton moved further than the skin: pair list to be rebuilt"}
# history columns
H_T, H_KE, H_U, H_WORK, H_DISS, H_R1, H_R2, H_U1, H_LINKED, H_KEROT = range(10)
N_H = 10


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True)
def compute_forces(x, phi, dx, dphi, vol, pi, pj, r0, area, linked, sig, tau, rprev, theta, dmg, kappa, alpha,
                   savg, fp, ip, f, mom, nvec, rr, theta_new, mfac, smean, seq, counters):
    """Update every pair's stress for the step's increments and return forces f and moments mom."""
    n_aut = x.shape[0]
    n_pair = pi.shape[0]
    g_mod = fp[F_G]
    lam = fp[F_LAM]
    kn = fp[F_KN]
    kc = fp[F_KC]
    mu = fp[F_MU]
    kind = ip[I_KIND]
    rot = ip[I_ROT]
    for i in range(n_aut):
        theta_new[i] = 0.0
        for c in range(3):
            f[i, c] = 0.0
            mom[i, c] = 0.0
    # pass 1: geometry and the automata's volume strain
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        rr[p] = r
        nvec[p, 0] = d0 / r
        nvec[p, 1] = d1 / r
        nvec[p, 2] = d2 / r
        if linked[p] == 1 or r < r0[p]:
            e = 0.5 * area[p] * (r - r0[p])
            theta_new[i] += e / vol[i]
            theta_new[j] += e / vol[j]
    # pass 2: incremental pair stresses
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        n0 = nvec[p, 0]
        n1 = nvec[p, 1]
        n2 = nvec[p, 2]
        r = rr[p]
        if linked[p] == 1:
            sig[p] += kn * (r - rprev[p]) / r0[p] + 0.5 * lam * ((theta_new[i] - theta[i]) + (theta_new[j] - theta[j]))
        else:
            sig[p] = kc * min(0.0, (r - r0[p]) / r0[p])
        t0 = tau[p, 0]
        t1 = tau[p, 1]
        t2 = tau[p, 2]
        tn = t0 * n0 + t1 * n1 + t2 * n2
        mag = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        t0 -= tn * n0
        t1 -= tn * n1
        t2 -= tn * n2
        mag2 = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
        if mag2 > 0.0:
            s = mag / mag2
            t0 *= s
            t1 *= s
            t2 *= s
        q = 0.5 * r0[p]
        e0 = dx[j, 0] - dx[i, 0]
        e1 = dx[j, 1] - dx[i, 1]
        e2 = dx[j, 2] - dx[i, 2]
        if rot == 1:
            c0, c1, c2 = _cross(dphi[i, 0] + dphi[j, 0], dphi[i, 1] + dphi[j, 1], dphi[i, 2] + dphi[j, 2], n0, n1, n2)
            e0 -= q * c0
            e1 -= q * c1
            e2 -= q * c2
        en = e0 * n0 + e1 * n1 + e2 * n2
        kt = 2.0 * g_mod / r0[p]
        t0 += kt * (e0 - en * n0)
        t1 += kt * (e1 - en * n1)
        t2 += kt * (e2 - en * n2)
        if linked[p] == 0:
            cap = mu * abs(sig[p])
            mag = math.sqrt(t0 * t0 + t1 * t1 + t2 * t2)
            if mag > cap:
                s = cap / mag if mag > 0.0 else 0.0
                t0 *= s
                t1 *= s
                t2 *= s
        tau[p, 0] = t0
        tau[p, 1] = t1
        tau[p, 2] = t2
        rprev[p] = r
    for i in range(n_aut):
        theta[i] = theta_new[i]
    need_state = kind != 0 or ip[I_FRACTURE] == 1
    if need_state:
        _average_stress(vol, pi, pj, r0, area, sig, tau, nvec, savg)
        for i in range(n_aut):
            mfac[i] = 1.0
            sm = (savg[i, 0] + savg[i, 1] + savg[i, 2]) / 3.0
            smean[i] = sm
            sint = _intensity(savg[i], sm)
            if kind == 2 or kind == 3:
                sy = fp[F_SY] + fp[F_HP] * alpha[i]
                if sint > sy:
                    dg = (sint - sy) / (3.0 * g_mod + fp[F_HP])
                    alpha[i] += dg
                    mfac[i] = (sy + fp[F_HP] * dg) / sint
                    for c in range(3):
                        savg[i, c] = sm + mfac[i] * (savg[i, c] - sm)
                        savg[i, 3 + c] *= mfac[i]
                    sint *= mfac[i]
            if kind == 1 or kind == 3:
                if sint > kappa[i]:
                    kappa[i] = sint
                if kappa[i] > fp[F_SD]:
                    dmg[i] = 1.0 - (fp[F_SD] + fp[F_HDE] * (kappa[i] - fp[F_SD])) / kappa[i]
            kdp = fp[F_KDP]
            seq[i] = (1.0 - dmg[i]) * (0.5 * (kdp + 1.0) * sint + 1.5 * (kdp - 1.0) * sm)
        if kind == 2 or kind == 3:
            for p in range(n_pair):
                if linked[p] == 1:
                    i = pi[p]
                    j = pj[p]
                    mb = 0.5 * (mfac[i] + mfac[j])
                    if mb < 1.0:
                        smb = 0.5 * (smean[i] + smean[j])
                        sig[p] = smb + mb * (sig[p] - smb)
                        for c in range(3):
                            tau[p, c] *= mb
        if ip[I_FRACTURE] == 1:
            for p in range(n_pair):
                if linked[p] == 1 and 0.5 * (seq[pi[p]] + seq[pj[p]]) >= fp[F_SC]:
                    linked[p] = 0
                    counters[C_UNLINK] += 1
                    sig[p] = kc * min(0.0, (rr[p] - r0[p]) / r0[p])
                    cap = mu * abs(sig[p])
                    mag = math.sqrt(tau[p, 0] ** 2 + tau[p, 1] ** 2 + tau[p, 2] ** 2)
                    if mag > cap:
                        for c in range(3):
                            tau[p, c] *= cap / mag
    if ip[I_RELINK] == 1:
        for p in range(n_pair):
            if linked[p] == 0 and sig[p] <= -fp[F_RELINK]:
                linked[p] = 1
                counters[C_RELINK] += 1
    # forces and moments
    krot = fp[F_KROT] * g_mod
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        db = area[p] * (1.0 - 0.5 * (dmg[i] + dmg[j]))
        s = sig[p]
        for c in range(3):
            fc = db * (s * nvec[p, c] + tau[p, c])
            f[i, c] += fc
            f[j, c] -= fc
        if rot == 1:
            q = 0.5 * r0[p]
            m0, m1, m2 = _cross(nvec[p, 0], nvec[p, 1], nvec[p, 2], tau[p, 0], tau[p, 1], tau[p, 2])
            mom[i, 0] += q * db * m0
            mom[i, 1] += q * db * m1
            mom[i, 2] += q * db * m2
            mom[j, 0] += q * db * m0
            mom[j, 1] += q * db * m1
            mom[j, 2] += q * db * m2
            if krot > 0.0 and linked[p] == 1:
                kr = krot * area[p] * r0[p]
                for c in range(3):
                    mr = kr * (phi[j, c] - phi[i, c])
                    mom[i, c] += mr
                    mom[j, c] -= mr


@njit(cache=True)
def _intensity(s, sm):
    """Stress intensity sqrt(3/2 s:s) of the symmetric tensor s = (xx, yy, zz, yz, xz, xy)."""
    a = s[0] - sm
    b = s[1] - sm
    c = s[2] - sm
    return math.sqrt(1.5 * (a * a + b * b + c * c + 2.0 * (s[3] * s[3] + s[4] * s[4] + s[5] * s[5])))


@njit(cache=True)
def _average_stress(vol, pi, pj, r0, area, sig, tau, nvec, savg):
    """sigma_i = (1/Omega_i) sum_j q S (sig n n + sym(n tau)), components (xx, yy, zz, yz, xz, xy)."""
    savg[:, :] = 0.0
    for p in range(pi.shape[0]):
        w = 0.5 * r0[p] * area[p]
        n0 = nvec[p, 0]
        n1 = nvec[p, 1]
        n2 = nvec[p, 2]
        s = sig[p]
        t0 = tau[p, 0]
        t1 = tau[p, 1]
        t2 = tau[p, 2]
        c0 = w * (s * n0 * n0 + n0 * t0)
        c1 = w * (s * n1 * n1 + n1 * t1)
        c2 = w * (s * n2 * n2 + n2 * t2)
        c3 = w * (s * n1 * n2 + 0.5 * (n1 * t2 + n2 * t1))
        c4 = w * (s * n0 * n2 + 0.5 * (n0 * t2 + n2 * t0))
        c5 = w * (s * n0 * n1 + 0.5 * (n0 * t1 + n1 * t0))
        for k in (pi[p], pj[p]):
            savg[k, 0] += c0
            savg[k, 1] += c1
            savg[k, 2] += c2
            savg[k, 3] += c3
            savg[k, 4] += c4
            savg[k, 5] += c5
    for i in range(savg.shape[0]):
        for c in range(6):
            savg[i, c] /= vol[i]


@njit(cache=True)
def potential_energy(vol, r0, area, linked, tau, rr, theta, fp):
    """Elastic energy sum_p [kn S (r - r0)^2 / (2 r0) + S r0 |tau|^2 / (4G)] + sum_i lam Omega theta^2 / 2
    (exact for the elastic, undamaged state the kernel integrates; unlinked pairs in contact use kc)."""
    u = 0.0
    g_mod = fp[F_G]
    for p in range(r0.shape[0]):
        dr = rr[p] - r0[p]
        if linked[p] == 1:
            u += 0.5 * fp[F_KN] * area[p] * dr * dr / r0[p]
        elif dr < 0.0:
            u += 0.5 * fp[F_KC] * area[p] * dr * dr / r0[p]
        u += area[p] * r0[p] * (tau[p, 0] ** 2 + tau[p, 1] ** 2 + tau[p, 2] ** 2) / (4.0 * g_mod)
    for i in range(vol.shape[0]):
        u += 0.5 * fp[F_LAM] * vol[i] * theta[i] * theta[i]
    return u


@njit(inline="always")
def _first_half(u, load, damp, m, inv_m, dt):
    """First half step of a free degree of freedom (velocity u, force or moment load, mass or inertia
    m): the exact damping factor, then half a kick.  Returns the new velocity and the energy damped.
    Scalars in and out: array arguments to an inlined helper cost reference counting in this loop
    (3-5x slower `advance`, measured)."""
    un = u * damp
    return un + 0.5 * dt * load * inv_m, 0.5 * m * (u * u - un * un)


@njit(inline="always")
def _second_half(u, load, damp, m, inv_m, dt):
    """Second half step of a free degree of freedom: half a kick, then the exact damping factor.
    Returns the new velocity and the energy damped."""
    uh = u + 0.5 * dt * load * inv_m
    un = uh * damp
    return un, 0.5 * m * (uh * uh - un * un)


@njit(cache=True)
def advance(x, v, phi, w, f, mom, dx, dphi, x0, xref, mass, inertia, vol, fixm, fixv, group,
            pi, pj, r0, area, linked, sig, tau, rprev, theta, dmg, kappa, alpha, savg, seq,
            fp, ip, nsteps, hist, counters, energy):
    """Advance `nsteps` velocity-Verlet steps (f, mom hold the forces of the current state on entry).

    Constrained degrees of freedom (fixm[i, c] = 1; c = 0..2 translation, 3..5 rotation) move with the
    prescribed velocity fixv[i, c] until time fp[F_TSTOP], then stay (the step across t_stop moves by the
    remaining fraction, so the prescribed displacement is reached exactly).  Viscous damping gamma (1/s) acts
    on the free ones (exact exponential decay per half step; the energy removed is accumulated).
    Work of the constraints: trapezoid of sum (-f) . v over each step.  A history row every ip[I_REC]
    steps.  Returns when done or when the state is non-finite, blows up, or moved beyond the skin."""
    n_aut = x.shape[0]
    n_pair = pi.shape[0]
    dt = fp[F_DT]
    damp = math.exp(-0.5 * fp[F_GAMMA] * dt)
    rot = ip[I_ROT]
    nvec = np.empty((n_pair, 3))
    rr = np.empty(n_pair)
    theta_new = np.empty(n_aut)
    mfac = np.ones(n_aut)
    smean = np.zeros(n_aut)
    inv_m = 1.0 / mass
    inv_j = 1.0 / inertia
    skin2 = fp[F_SKIN] * fp[F_SKIN]
    power_old = _power(f, mom, v, w, fixm, rot)
    for _ in range(nsteps):
        t = fp[F_T]
        drive = min(1.0, max(0.0, (fp[F_TSTOP] - t) / dt))  # the last partial step lands on t_stop exactly
        diss = 0.0
        for i in range(n_aut):
            for c in range(3):
                if fixm[i, c] == 1:
                    v[i, c] = fixv[i, c] * drive
                else:
                    v[i, c], e = _first_half(v[i, c], f[i, c], damp, mass[i], inv_m[i], dt)
                    diss += e
                dx[i, c] = dt * v[i, c]
                x[i, c] += dx[i, c]
                if rot == 1:
                    if fixm[i, 3 + c] == 1:
                        w[i, c] = fixv[i, 3 + c] * drive
                    else:
                        w[i, c], e = _first_half(w[i, c], mom[i, c], damp, inertia[i], inv_j[i], dt)
                        diss += e
                    dphi[i, c] = dt * w[i, c]
                    phi[i, c] += dphi[i, c]
        fp[F_T] = t + dt
        compute_forces(x, phi, dx, dphi, vol, pi, pj, r0, area, linked, sig, tau, rprev, theta, dmg, kappa,
                       alpha, savg, fp, ip, f, mom, nvec, rr, theta_new, mfac, smean, seq, counters)
        ke = 0.0
        kerot = 0.0
        moved = False
        for i in range(n_aut):
            for c in range(3):
                if fixm[i, c] == 0:
                    v[i, c], e = _second_half(v[i, c], f[i, c], damp, mass[i], inv_m[i], dt)
                    diss += e
                ke += 0.5 * mass[i] * v[i, c] * v[i, c]
                if rot == 1:
                    if fixm[i, 3 + c] == 0:
                        w[i, c], e = _second_half(w[i, c], mom[i, c], damp, inertia[i], inv_j[i], dt)
                        diss += e
                    kerot += 0.5 * inertia[i] * w[i, c] * w[i, c]
            dd = (x[i, 0] - xref[i, 0]) ** 2 + (x[i, 1] - xref[i, 1]) ** 2 + (x[i, 2] - xref[i, 2]) ** 2
            if dd > skin2:
                moved = True
        power = _power(f, mom, v, w, fixm, rot)
        energy[E_WORK] += 0.5 * dt * (power_old + power)
        energy[E_DISS] += diss
        power_old = power
        counters[C_STEPS] += 1
        counters[C_PAIRSTEPS] += n_pair
        rec = ip[I_REC] > 0 and counters[C_STEPS] % ip[I_REC] == 0 and counters[C_ROWS] < hist.shape[0]
        if not (math.isfinite(ke) and math.isfinite(kerot)):
            counters[C_STATUS] = NAN
            return
        if ke + kerot > fp[F_KEMAX]:
            counters[C_STATUS] = GROWTH
            rec = counters[C_ROWS] < hist.shape[0]
        if rec:
            _record(hist, counters, fp, ke, kerot, energy, vol, r0, area, linked, tau, rr, theta, f, group, x, x0)
        if counters[C_STATUS] != OK:
            return
        if moved:
            counters[C_STATUS] = MOVED
            return


@njit(cache=True)
def _power(f, mom, v, w, fixm, rot):
    """Power of the constraints on the automata: sum over constrained dofs of (-force) . velocity."""
    pw = 0.0
    for i in range(f.shape[0]):
        for c in range(3):
            if fixm[i, c] == 1:
                pw -= f[i, c] * v[i, c]
            if rot == 1 and fixm[i, 3 + c] == 1:
                pw -= mom[i, c] * w[i, c]
    return pw


@njit(cache=True)
def _record(hist, counters, fp, ke, kerot, energy, vol, r0, area, linked, tau, rr, theta, f, group, x, x0):
    row = counters[C_ROWS]
    r1 = 0.0
    r2 = 0.0
    u1 = 0.0
    n1 = 0
    for i in range(f.shape[0]):
        if group[i] == 1:
            r1 -= f[i, 2]
            u1 += x[i, 2] - x0[i, 2]
            n1 += 1
        elif group[i] == 2:
            r2 -= f[i, 2]
    nl = 0
    for p in range(linked.shape[0]):
        nl += linked[p]
    hist[row, H_T] = fp[F_T]
    hist[row, H_KE] = ke + kerot
    hist[row, H_U] = potential_energy(vol, r0, area, linked, tau, rr, theta, fp)
    hist[row, H_WORK] = energy[E_WORK]
    hist[row, H_DISS] = energy[E_DISS]
    hist[row, H_R1] = r1
    hist[row, H_R2] = r2
    hist[row, H_U1] = u1 / max(n1, 1)
    hist[row, H_LINKED] = nl
    hist[row, H_KEROT] = kerot
    counters[C_ROWS] = row + 1
