"""Numba kernel of the MCA mechanics: pair and many-body forces in incremental form, velocity Verlet.

The pair state (normal and tangential stress, linked or not), its objective incremental update and the automata's
inelastic state (docs/physics.md, "The MCA solver in detail").  A kernel takes (state, params, nsteps): `State` and
`Params` are NamedTuples numba compiles as structures; the parts a scene may not need (rotations, inelastic state,
loads, contact, a moving damping frame) are None, so numba prunes their branches; each combination compiles once.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import contact as ct

# fix kinds of a degree of freedom (State.fixm)
FREE, PRESCRIBED = 0, 1
# counters
C_STEPS, C_STATUS, C_UNLINK, C_RELINK, C_PAIRSTEPS, C_ROWS = range(6)
N_C = 6
# energy accumulators: work of the prescribed motions, energy removed by damping, work of the loads, energy
# dissipated by contact friction
E_WORK, E_DISS, E_LOAD, E_FRIC = range(4)
N_E = 4
# status codes
OK, NAN, GROWTH, MOVED = 0, 1, 2, 3
STATUS_TEXT = {OK: "ok", NAN: "non-finite state", GROWTH: "kinetic energy above the blow-up limit",
               MOVED: "an automaton moved further than the skin: pair list to be rebuilt"}
# history columns
H_T, H_KE, H_U, H_WORK, H_DISS, H_R1, H_R2, H_U1, H_LINKED, H_KEROT, H_LOAD, H_FRIC, H_FT, H_FN, H_NC = range(15)
N_H = 15
HISTORY_COLUMNS = ("t", "kinetic", "potential", "work", "dissipated", "reaction_zL", "reaction_z0", "u_zL", "linked",
                   "kinetic_rot", "load_work", "friction_heat", "friction_force", "normal_force", "contacts")


class Rotation(NamedTuple):
    """Rotational degrees of freedom: angles, angular velocities, moments, the step's increments, inertia."""

    phi: np.ndarray  # (N, 3)
    w: np.ndarray  # (N, 3)
    mom: np.ndarray  # (N, 3)
    dphi: np.ndarray  # (N, 3)
    inertia: np.ndarray  # (N,)


class Inelastic(NamedTuple):
    """Automaton state of response functions and fracture: damage, kappa, plastic strain, average stress,
    equivalent stress, and two scratch arrays (return factor, mean stress)."""

    dmg: np.ndarray
    kappa: np.ndarray
    alpha: np.ndarray
    savg: np.ndarray  # (N, 6): xx, yy, zz, yz, xz, xy
    seq: np.ndarray
    mfac: np.ndarray
    smean: np.ndarray


class Load(NamedTuple):
    """External forces on the automata (N), constant during a run."""

    force: np.ndarray  # (N, 3)


class Frame(NamedTuple):
    """Reference velocities (N, 3) that damping acts relative to (scaled by the drive's ramp): a body driven
    along at V is damped about its rigid motion at V, not about rest."""

    vel: np.ndarray


class Spring(NamedTuple):
    """A drive spring (N/m) whose far end moves along `axis` at `speed` from `start`, pulling the automata by
    `weight` (m_i / M on the driven body: at its centre of mass) with extension V (t - start)+ - (u - offset), u
    the weighted mean displacement; `out`: force, u, work; every `every` steps a row (t, force, velocity, u)."""

    weight: np.ndarray  # (N,)
    axis: int
    stiffness: float
    speed: float
    start: float
    offset: float
    every: int
    out: np.ndarray  # (3,)
    hist: np.ndarray  # (rows, 4)
    rows: np.ndarray  # (1,) int64


class State(NamedTuple):
    """Every array of a mechanical run: fixed during it (rest positions, masses, volumes, fixes, face groups,
    the pair list), then what a step advances; the optional parts are None when the run has none."""

    x0: np.ndarray
    mass: np.ndarray
    vol: np.ndarray
    fixm: np.ndarray  # (N, 6) uint8
    fixv: np.ndarray  # (N, 6)
    group: np.ndarray  # (N,) 1 = driven face, 2 = opposite face
    pi: np.ndarray
    pj: np.ndarray
    r0: np.ndarray
    area: np.ndarray
    x: np.ndarray
    v: np.ndarray
    f: np.ndarray
    dx: np.ndarray
    xref: np.ndarray
    linked: np.ndarray
    sig: np.ndarray
    tau: np.ndarray
    rprev: np.ndarray
    theta: np.ndarray
    clock: np.ndarray  # (1,) time (s)
    counters: np.ndarray
    energy: np.ndarray
    hist: np.ndarray  # (rows, N_H)
    rot: Rotation | None
    inel: Inelastic | None
    load: Load | None
    contact: ct.ContactState | None
    frame: Frame | None = None
    peak: np.ndarray | None = None  # (3,) largest driven-face reaction so far, its face displacement, its step
    spring: Spring | None = None


class Params(NamedTuple):
    """Scalars of a mechanical run (SI units).  kind: response function code (response.KINDS); with ramp > 0
    the prescribed velocities rise smoothly from 0 at ramp_start to fixv at ramp_start + ramp."""

    dt: float
    shear: float
    lam: float
    kn: float
    kc: float
    mu: float
    gamma: float
    t_stop: float
    skin: float
    ke_max: float
    krot: float
    relink: float
    sigma_c: float
    kdp: float
    sigma_y: float
    hp: float
    sigma_d: float
    hde: float
    kind: int
    fracture: bool
    relink_on: bool
    record_every: int
    ramp_start: float = 0.0
    ramp: float = 0.0


@njit(cache=True)
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(inline="always")
def _turn(v0, v1, v2, w0, w1, w2, ra, rb):
    """(R - I) v = ra w x v + rb w x (w x v): what the rotation by the rotation vector w adds to v (Rodrigues;
    ra, rb its coefficients sin|w| / |w|, (1 - cos|w|) / |w|^2)."""
    c0, c1, c2 = _cross(w0, w1, w2, v0, v1, v2)
    b0, b1, b2 = _cross(w0, w1, w2, c0, c1, c2)
    return ra * c0 + rb * b0, ra * c1 + rb * b1, ra * c2 + rb * b2


@njit(cache=True)
def forces(st, par):
    """Forces (and moments) of the current positions for the step's increments st.dx (and dphi): one
    evaluation of the pair-force function, outside time stepping."""
    _evaluate(st, par, st.rot, st.inel, st.load, st.contact)
    _spring_force(st.f, st.x, st.x0, st.clock[0], st.spring)


@njit(cache=True)
def _evaluate(st, par, rot, inel, load, con):
    n_pair = st.pi.shape[0]
    _forces(st, par, rot, inel, load, con, np.empty((n_pair, 3)), np.empty(n_pair), np.empty(st.x.shape[0]))


@njit(cache=True, inline="always")
def _forces(st, par, rot, inel, load, con, nvec, rr, theta_new):
    """The pair-force function: update every pair's stress for the step's increments and return the forces
    st.f (and moments rot.mom); nvec, rr, theta_new are scratch (pair normals, lengths, new volume strains).
    Inlined into its callers (whose None arguments then prune it): called per step with the state, it cost
    a reference count per array of the state, 2-5 % of a step at n = 4."""
    x, pi, pj, r0, area, linked, sig, tau, rprev, theta = (st.x, st.pi, st.pj, st.r0, st.area, st.linked, st.sig,
                                                          st.tau, st.rprev, st.theta)
    f = st.f
    n_aut = x.shape[0]
    n_pair = pi.shape[0]
    g_mod = par.shear
    lam = par.lam
    kn = par.kn
    kc = par.kc
    mu = par.mu
    for i in range(n_aut):
        theta_new[i] = 0.0
        for c in range(3):
            f[i, c] = 0.0
            if rot is not None:
                rot.mom[i, c] = 0.0
    # pass 1: geometry and the automata's volume strain
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        d0 = x[j, 0] - x[i, 0]
        d1 = x[j, 1] - x[i, 1]
        d2 = x[j, 2] - x[i, 2]
        r = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        rr[p] = r
        ir = 1.0 / r
        nvec[p, 0] = d0 * ir
        nvec[p, 1] = d1 * ir
        nvec[p, 2] = d2 * ir
        if linked[p] == 1 or r < r0[p]:
            e = 0.5 * area[p] * (r - r0[p])
            theta_new[i] += e / st.vol[i]
            theta_new[j] += e / st.vol[j]
    if con is not None:
        ct.geometry(x, st.vol, con, theta_new)
    # pass 2: incremental pair stresses
    dx = st.dx
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        n0 = nvec[p, 0]
        n1 = nvec[p, 1]
        n2 = nvec[p, 2]
        r = rr[p]
        ir0 = 1.0 / r0[p]
        if linked[p] == 1:
            sig[p] += kn * (r - rprev[p]) * ir0 + 0.5 * lam * ((theta_new[i] - theta[i]) + (theta_new[j] - theta[j]))
        else:
            sig[p] = kc * min(0.0, (r - r0[p]) * ir0)
        # the step's relative displacement, the pair's rotation R over the step (the exact rotation by the mean
        # spin increment w = (dphi_i + dphi_j) / 2, the identity without rotations; Rodrigues: R v = v + a w x v
        # + b w x (w x v), a = sin|w| / |w|, b = (1 - cos|w|) / |w|^2, by series below |w| = 0.01, exact to
        # round-off there and no trigonometry in the common case) and the tangential increment e = d_new -
        # R d_old = (dx_j - dx_i) - (R - I) d_old, zero for a rigid motion
        e0 = dx[j, 0] - dx[i, 0]
        e1 = dx[j, 1] - dx[i, 1]
        e2 = dx[j, 2] - dx[i, 2]
        t0 = tau[p, 0]
        t1 = tau[p, 1]
        t2 = tau[p, 2]
        if rot is not None:
            dphi = rot.dphi
            w0 = 0.5 * (dphi[i, 0] + dphi[j, 0])
            w1 = 0.5 * (dphi[i, 1] + dphi[j, 1])
            w2 = 0.5 * (dphi[i, 2] + dphi[j, 2])
            ww = w0 * w0 + w1 * w1 + w2 * w2
            if ww < 1e-4:
                ra = 1.0 - ww * (1.0 / 6.0) * (1.0 - ww * (1.0 / 20.0))
                rb = 0.5 - ww * (1.0 / 24.0) * (1.0 - ww * (1.0 / 30.0))
            else:
                wn = math.sqrt(ww)
                ra = math.sin(wn) / wn
                rb = math.sin(0.5 * wn) / wn
                rb = 2.0 * rb * rb
            g0, g1, g2 = _turn(r * n0 - e0, r * n1 - e1, r * n2 - e2, w0, w1, w2, ra, rb)
            e0 -= g0
            e1 -= g1
            e2 -= g2
            g0, g1, g2 = _turn(t0, t1, t2, w0, w1, w2, ra, rb)
            t0 += g0
            t1 += g1
            t2 += g2
        # tau turned by R is tangent to m = R n_old; the smallest rotation taking m to n turns such a vector v
        # into v - (n.v) (m + n) / (1 + m.n), tangent to n; with m = (d - e) / rprev (|R d_old| = the old
        # length), d = r n: v - (n.v) ((r + rprev) n - e) / (r + rprev - n.e)
        tn = t0 * n0 + t1 * n1 + t2 * n2
        en = e0 * n0 + e1 * n1 + e2 * n2
        rs = r + rprev[p]
        s = tn / (rs - en)
        kt = 2.0 * g_mod * ir0
        ke = kt + s
        cn = kt * en + s * rs
        t0 += ke * e0 - cn * n0
        t1 += ke * e1 - cn * n1
        t2 += ke * e2 - cn * n2
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
    if inel is not None:
        _inelastic(pi, pj, r0, area, linked, sig, tau, st.vol, st.counters, par, inel, nvec, rr)
    if par.relink_on:
        for p in range(n_pair):
            if linked[p] == 0 and sig[p] <= -par.relink:
                linked[p] = 1
                st.counters[C_RELINK] += 1
    # forces and moments
    krot = par.krot * g_mod
    for p in range(n_pair):
        i = pi[p]
        j = pj[p]
        if inel is not None:
            db = area[p] * (1.0 - 0.5 * (inel.dmg[i] + inel.dmg[j]))
        else:
            db = area[p]
        s = sig[p]
        for c in range(3):
            fc = db * (s * nvec[p, c] + tau[p, c])
            f[i, c] += fc
            f[j, c] -= fc
        if rot is not None:
            mom = rot.mom
            q = 0.5 * rr[p]  # the contact point at the pair's midpoint, as in the tangential increment
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
                    mr = kr * (rot.phi[j, c] - rot.phi[i, c])
                    mom[i, c] += mr
                    mom[j, c] -= mr
    if con is not None:
        ct.forces(x, st.v, f, theta, st.mass, kn, lam, par.dt, con, rot)
    if load is not None:
        for i in range(n_aut):
            for c in range(3):
                f[i, c] += load.force[i, c]


@njit(cache=True)
def _inelastic(pi, pj, r0, area, linked, sig, tau, vol, counters, par, inel, nvec, rr):
    """Average stress, plastic return, damage and fracture of the automata (response functions:
    docs/physics.md, "The movable cellular automaton (MCA) model").
    Arrays, not the state: a structure passed to a function per step costs a reference count per array."""
    n_aut = vol.shape[0]
    n_pair = pi.shape[0]
    kind = par.kind
    g_mod = par.shear
    savg, mfac, smean, alpha, kappa, dmg, seq = inel.savg, inel.mfac, inel.smean, inel.alpha, inel.kappa, inel.dmg, \
        inel.seq
    _average_stress(vol, pi, pj, r0, area, sig, tau, nvec, savg)
    for i in range(n_aut):
        mfac[i] = 1.0
        sm = (savg[i, 0] + savg[i, 1] + savg[i, 2]) / 3.0
        smean[i] = sm
        sint = _intensity(savg[i], sm)
        if kind == 2 or kind == 3:
            sy = par.sigma_y + par.hp * alpha[i]
            if sint > sy:
                dg = (sint - sy) / (3.0 * g_mod + par.hp)
                alpha[i] += dg
                mfac[i] = (sy + par.hp * dg) / sint
                for c in range(3):
                    savg[i, c] = sm + mfac[i] * (savg[i, c] - sm)
                    savg[i, 3 + c] *= mfac[i]
                sint *= mfac[i]
        if kind == 1 or kind == 3:
            if sint > kappa[i]:
                kappa[i] = sint
            if kappa[i] > par.sigma_d:
                dmg[i] = 1.0 - (par.sigma_d + par.hde * (kappa[i] - par.sigma_d)) / kappa[i]
        kdp = par.kdp
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
    if par.fracture:
        kc = par.kc
        mu = par.mu
        for p in range(n_pair):
            if linked[p] == 1 and 0.5 * (seq[pi[p]] + seq[pj[p]]) >= par.sigma_c:
                linked[p] = 0
                counters[C_UNLINK] += 1
                sig[p] = kc * min(0.0, (rr[p] - r0[p]) / r0[p])
                cap = mu * abs(sig[p])
                mag = math.sqrt(tau[p, 0] ** 2 + tau[p, 1] ** 2 + tau[p, 2] ** 2)
                if mag > cap:
                    for c in range(3):
                        tau[p, c] *= cap / mag


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
def potential_energy(st, par, rr):
    """Elastic energy sum_p [kn S (r - r0)^2 / (2 r0) + S r0 |tau|^2 / (4G)] + sum_i lam Omega theta^2 / 2, with
    rotations + sum_p krot G S r0 |phi_j - phi_i|^2 / 2 over the linked pairs (the springs whose moments the
    kernel applies); exact for the elastic, undamaged state the kernel integrates; unlinked pairs in contact use
    kc; rr: the pairs' current lengths."""
    u = 0.0
    g_mod = par.shear
    r0, area, linked, tau, theta, vol = st.r0, st.area, st.linked, st.tau, st.theta, st.vol
    for p in range(r0.shape[0]):
        dr = rr[p] - r0[p]
        if linked[p] == 1:
            u += 0.5 * par.kn * area[p] * dr * dr / r0[p]
        elif dr < 0.0:
            u += 0.5 * par.kc * area[p] * dr * dr / r0[p]
        u += area[p] * r0[p] * (tau[p, 0] ** 2 + tau[p, 1] ** 2 + tau[p, 2] ** 2) / (4.0 * g_mod)
    for i in range(vol.shape[0]):
        u += 0.5 * par.lam * vol[i] * theta[i] * theta[i]
    return u + _rotation_energy(st, par, st.rot)


@njit(cache=True)
def _rotation_energy(st, par, rot):
    """sum over the linked pairs of krot G S r0 |phi_j - phi_i|^2 / 2 (0 without rotations: numba prunes the
    branch on the argument's type, so a kernel without rotations has no rotation code)."""
    if rot is None or par.krot <= 0.0:
        return 0.0
    kr = 0.5 * par.krot * par.shear
    phi = rot.phi
    u = 0.0
    for p in range(st.r0.shape[0]):
        if st.linked[p] == 1:
            i = st.pi[p]
            j = st.pj[p]
            d0 = phi[j, 0] - phi[i, 0]
            d1 = phi[j, 1] - phi[i, 1]
            d2 = phi[j, 2] - phi[i, 2]
            u += kr * st.area[p] * st.r0[p] * (d0 * d0 + d1 * d1 + d2 * d2)
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
def advance(st, par, nsteps):
    """Advance `nsteps` velocity-Verlet steps (st.f and the moments hold the forces of the current state on
    entry), leaving the status in st.counters[C_STATUS]: done, non-finite, blown up or moved beyond the skin.
    Prescribed degrees of freedom move with fixv until par.t_stop (the step across it by the remaining
    fraction, so the prescribed displacement is exact), then stay.  Viscous damping decays the free ones'
    velocities (relative to st.frame's) exactly per half step.  The works of the prescribed motions and the
    loads are trapezoids over each step; a history row every par.record_every steps."""
    _advance(st, par, st.rot, st.inel, st.load, st.contact, st.frame, st.peak, st.spring, nsteps)


@njit(cache=True)
def _advance(st, par, rot, inel, load, con, frame, peak, spring, nsteps):
    x, v, f, dx, fixm, fixv, mass = st.x, st.v, st.f, st.dx, st.fixm, st.fixv, st.mass
    counters = st.counters
    n_aut = x.shape[0]
    n_pair = st.pi.shape[0]
    dt = par.dt
    damp = math.exp(-0.5 * par.gamma * dt)
    nvec = np.empty((n_pair, 3))
    rr = np.empty(n_pair)
    theta_new = np.empty(n_aut)
    inv_m = 1.0 / mass
    if rot is not None:
        inertia = rot.inertia
        inv_j = 1.0 / inertia
    skin2 = par.skin * par.skin
    power_old = _power(f, v, fixm, rot)
    load_old = _load_power(v, load)
    for _ in range(nsteps):
        t = st.clock[0]
        drive = _drive(par, t, dt)
        diss = 0.0
        for i in range(n_aut):
            for c in range(3):
                if fixm[i, c] == PRESCRIBED:
                    v[i, c] = fixv[i, c] * drive
                elif frame is not None:
                    ref = frame.vel[i, c] * drive
                    un = ref + (v[i, c] - ref) * damp
                    diss += 0.5 * mass[i] * (v[i, c] * v[i, c] - un * un)
                    v[i, c] = un + 0.5 * dt * f[i, c] * inv_m[i]
                else:
                    v[i, c], e = _first_half(v[i, c], f[i, c], damp, mass[i], inv_m[i], dt)
                    diss += e
                dx[i, c] = dt * v[i, c]
                x[i, c] += dx[i, c]
                if rot is not None:
                    w = rot.w
                    if fixm[i, 3 + c] == PRESCRIBED:
                        w[i, c] = fixv[i, 3 + c] * drive
                    else:
                        w[i, c], e = _first_half(w[i, c], rot.mom[i, c], damp, inertia[i], inv_j[i], dt)
                        diss += e
                    rot.dphi[i, c] = dt * w[i, c]
                    rot.phi[i, c] += rot.dphi[i, c]
        st.clock[0] = t + dt
        _forces(st, par, rot, inel, load, con, nvec, rr, theta_new)
        _spring_force(f, x, st.x0, st.clock[0], spring)
        _track_frame(v, f, inv_m, dt, spring, frame)
        ke = 0.0
        kerot = 0.0
        moved = False
        for i in range(n_aut):
            for c in range(3):
                if fixm[i, c] == FREE:
                    if frame is not None:
                        ref = frame.vel[i, c] * drive
                        uh = v[i, c] + 0.5 * dt * f[i, c] * inv_m[i]
                        vn = ref + (uh - ref) * damp
                        diss += 0.5 * mass[i] * (uh * uh - vn * vn)
                        v[i, c] = vn
                    else:
                        v[i, c], e = _second_half(v[i, c], f[i, c], damp, mass[i], inv_m[i], dt)
                        diss += e
                ke += 0.5 * mass[i] * v[i, c] * v[i, c]
                if rot is not None:
                    w = rot.w
                    if fixm[i, 3 + c] == FREE:
                        w[i, c], e = _second_half(w[i, c], rot.mom[i, c], damp, inertia[i], inv_j[i], dt)
                        diss += e
                    kerot += 0.5 * inertia[i] * w[i, c] * w[i, c]
            dd = (x[i, 0] - st.xref[i, 0]) ** 2 + (x[i, 1] - st.xref[i, 1]) ** 2 + (x[i, 2] - st.xref[i, 2]) ** 2
            if dd > skin2:
                moved = True
        power = _power(f, v, fixm, rot)
        st.energy[E_WORK] += 0.5 * dt * (power_old + power)
        st.energy[E_DISS] += diss
        power_old = power
        if load is not None:
            load_new = _load_power(v, load)
            st.energy[E_LOAD] += 0.5 * dt * (load_old + load_new)
            load_old = load_new
        if con is not None:
            st.energy[E_FRIC] += ct.after_step(con, dt)
        counters[C_STEPS] += 1
        counters[C_PAIRSTEPS] += n_pair
        _spring_after(v, st.clock[0], dt, counters[C_STEPS], spring)
        if peak is not None:
            _track_peak(peak, f, x, st.x0, st.group, counters[C_STEPS])
        hist = st.hist
        rec = par.record_every > 0 and counters[C_STEPS] % par.record_every == 0 and counters[C_ROWS] < hist.shape[0]
        if not (math.isfinite(ke) and math.isfinite(kerot)):
            counters[C_STATUS] = NAN
            return
        if ke + kerot > par.ke_max:
            counters[C_STATUS] = GROWTH
            rec = counters[C_ROWS] < hist.shape[0]
        if rec:
            _record(st, par, con, ke, kerot, rr)
        if counters[C_STATUS] != OK:
            return
        if moved:
            counters[C_STATUS] = MOVED
            return


@njit(cache=True)
def _spring_force(f, x, x0, t, spring):
    """Add the drive spring's force k (V (t - start)+ - (u - offset)) to the automata by their weights (none
    without a spring); its force and u go to spring.out."""
    if spring is None:
        return
    d = spring.axis
    u = 0.0
    for i in range(x.shape[0]):
        u += spring.weight[i] * (x[i, d] - x0[i, d])
    force = spring.stiffness * (spring.speed * max(0.0, t - spring.start) - (u - spring.offset))
    for i in range(x.shape[0]):
        f[i, d] += spring.weight[i] * force
    spring.out[0] = force
    spring.out[1] = u


@njit(cache=True)
def _spring_after(v, t, dt, step, spring):
    """The drive spring over the step just taken: its work and its history row."""
    if spring is None:
        return
    d = spring.axis
    vel = 0.0
    for i in range(v.shape[0]):
        vel += spring.weight[i] * v[i, d]
    spring.out[2] += spring.out[0] * vel * dt
    row = spring.rows[0]
    if step % spring.every == 0 and row < spring.hist.shape[0]:
        spring.hist[row, 0] = t
        spring.hist[row, 1] = spring.out[0]
        spring.hist[row, 2] = vel
        spring.hist[row, 3] = spring.out[1]
        spring.rows[0] = row + 1


@njit(cache=True)
def _track_frame(v, f, inv_m, dt, spring, frame):
    """With a drive spring and a damping frame: the driven body's reference velocity set to its mean velocity
    after this step's second half kick, before the damping acts on it.  The damping then keeps that mean, so its
    resultant on the body is zero in both half steps (the mean of the step before would drag an accelerating
    body by its mass x acceleration x gamma dt / 2)."""
    if spring is None or frame is None:
        return
    d = spring.axis
    vel = 0.0
    for i in range(v.shape[0]):
        vel += spring.weight[i] * (v[i, d] + 0.5 * dt * f[i, d] * inv_m[i])
    for i in range(v.shape[0]):
        if spring.weight[i] > 0.0:
            frame.vel[i, d] = vel


@njit(cache=True)
def _track_peak(peak, f, x, x0, group, step):
    """Every step, not every history row: the largest reaction of the driven face (group 1), its mean
    displacement and the step, so a thinned history does not move the peak it reports."""
    r1, _, u1 = _face_reactions(f, x, x0, group)
    if r1 > peak[0]:
        peak[0] = r1
        peak[1] = u1
        peak[2] = step


@njit(cache=True)
def _face_reactions(f, x, x0, group):
    """(reaction of the driven face (group 1), reaction of the opposite face (group 2), the driven face's mean
    displacement), all along z."""
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
    return r1, r2, u1 / max(n1, 1)


@njit(cache=True)
def _drive(par, t, dt):
    """Factor of the prescribed velocities over the step from t: the stop (the last partial step lands on
    t_stop exactly) times the smooth ramp."""
    drive = min(1.0, max(0.0, (par.t_stop - t) / dt))
    if par.ramp > 0.0:
        drive *= _smoothstep((t + 0.5 * dt - par.ramp_start) / par.ramp)
    return drive


@njit(inline="always")
def _smoothstep(s):
    """0 below 0, 1 above 1, s^2 (3 - 2 s) between: a velocity ramp with continuous acceleration."""
    s = min(1.0, max(0.0, s))
    return s * s * (3.0 - 2.0 * s)


@njit(cache=True)
def _power(f, v, fixm, rot):
    """Power of the prescribed motions on the automata: sum over prescribed dofs of (-force) . velocity."""
    pw = 0.0
    for i in range(f.shape[0]):
        for c in range(3):
            if fixm[i, c] == PRESCRIBED:
                pw -= f[i, c] * v[i, c]
            if rot is not None:
                if fixm[i, 3 + c] == PRESCRIBED:
                    pw -= rot.mom[i, c] * rot.w[i, c]
    return pw


@njit(cache=True)
def _load_power(v, load):
    """Power of the external loads: sum f_load . v."""
    pw = 0.0
    if load is not None:
        for i in range(v.shape[0]):
            for c in range(3):
                pw += load.force[i, c] * v[i, c]
    return pw


@njit(cache=True)
def _record(st, par, con, ke, kerot, rr):
    hist, counters, f, x, x0, group = st.hist, st.counters, st.f, st.x, st.x0, st.group
    row = counters[C_ROWS]
    r1, r2, u1 = _face_reactions(f, x, x0, group)
    nl = 0
    for p in range(st.linked.shape[0]):
        nl += st.linked[p]
    hist[row, H_T] = st.clock[0]
    hist[row, H_KE] = ke + kerot
    hist[row, H_U] = potential_energy(st, par, rr)
    hist[row, H_WORK] = st.energy[E_WORK]
    hist[row, H_DISS] = st.energy[E_DISS]
    hist[row, H_R1] = r1
    hist[row, H_R2] = r2
    hist[row, H_U1] = u1
    hist[row, H_LINKED] = nl
    hist[row, H_KEROT] = kerot
    hist[row, H_LOAD] = st.energy[E_LOAD]
    if con is not None:
        hist[row, H_U] += ct.energy(con, par.kn)
        hist[row, H_FRIC] = st.energy[E_FRIC]
        hist[row, H_FT], hist[row, H_FN], hist[row, H_NC] = ct.resultants(con)
    counters[C_ROWS] = row + 1
