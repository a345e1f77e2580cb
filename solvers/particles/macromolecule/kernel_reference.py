"""Velocity-Verlet kernel of the macromolecule model with its fixes and computes in one loop.

This is the plain reference kernel (pair list, array-of-structures); the fast kernels
(`kernel_fast`) integrate the same scheme faster and are tested equal to it to rounding.  All take
the structures of `kernel_state` (one signature) and are chosen from `kernels.KERNELS`.

Fixes (what a particle's motion is):
  FREE        Newton, optionally with a Langevin bath (gamma, kT): exact OU factor, then kick;
              kT = 0 makes it an absorbing (viscous) face.
  FROZEN      x = x_rest, v = 0.
  PRESCRIBED  x = x_rest + amp * sin(omega t + phase) (kinematic drive, each particle on its own).
  GROUP       x = x_rest + c(t) + amp * sin(omega t): two rigid sides of the red pair whose relative
              motion is prescribed; with `free_centre` the common displacement c obeys
              M_group c'' = sum of forces on the group (the relative motion shares itself in
              inverse proportion to the masses), else c = 0 (each side fully prescribed).

Time stepping (kick-drift form of velocity Verlet, v_n = (v_{n-1/2} + v_{n+1/2}) / 2):
  v_{n+1/2} = v_{n-1/2} + dt (Fc(x_n) + Fd(x_n, v_{n-1/2}) + lambda_n) / m
  x_{n+1}   = x_n + dt v_{n+1/2}
The radial pair damping Fd = delta * rdot e uses the half-step velocity v_{n-1/2}: the
"half-step predictor" of DPD-VV (lambda = 1/2).  It is explicit, one force pass per step,
second order for the conservative part and first order in the dissipative part; for a mode of
frequency omega and damping ratio zeta it is stable for omega dt < 2 (sqrt(1 + zeta^2) - zeta)
(the central-difference limit with lagged damping).  lambda_n is whatever a fix adds (drive or
bath force), defined by m (v_{n+1/2} - v_{n-1/2}) / dt - F_n, so every particle obeys the same
two lines and the discrete energy identity below holds for all of them.

Energy accounting (exact algebra, per step n -> n+1):
  E_n = sum 1/2 m v_{n-1/2} . v_{n+1/2} + U(x_n)    (the leapfrog energy; conserved exactly by
                                                    a harmonic lattice, so it shows only
                                                    the anharmonic trapezoid error)
  E_{n+1} - E_n = 1/2 dt v_{n+1/2} . (Fd_n + Fd_{n+1}) + 1/2 dt v_{n+1/2} . (lambda_n + lambda_{n+1})
                  + [1/2 dt v_{n+1/2} . (Fc_n + Fc_{n+1}) + U_{n+1} - U_n]
The first sum is minus the dissipated energy, the second the drive (or bath) work, the bracket
the quadrature error of the conservative work, O(|dx|^3 F'') per pair-step: the balance error.

What the balance error is (measured).  The dissipation and drive work above are what
the scheme applies, so the residual E_end - E_start + dissipated - work is exactly the sum of
the per-pair brackets (checked to 1e-10 with an instrumented kernel).  It vanishes for a
harmonic lattice: with every pair force replaced by its linearisation at the rest root (same
lattice, drive, damping, dt) the n = 5, zeta = 0.01 run closes to 3e-8 (D = 0.005) and 2e-7 (D =
0.02).  With the seven-root force the same runs leave 2.5e-3 and 1.9e-3 of the drive work at
safety 0.1, falling as dt^2 (3.1e-3 -> 7.8e-4, 2.0e-3 -> 5.0e-4 from safety 0.1 to 0.05 over 15
s), and it sits in one bond, the shell-a bond between the red pair's lower particle and the
particle below it (1.39e-11 J of the 1.24e-11 J residual; all other pairs together -0.15e-11 J):
the drive at f = f_top puts the x = 0, z = 0 column below the red pair into a nonlinear
resonance (bond excursion +-2 to +-4 % of a, nearly independent of D; with linear forces the
same bond moves +-0.006 % of a).  So the residual is the genuine O(dt^2) integration error of
velocity Verlet on the anharmonic force in that resonance, not bookkeeping and not the damping
treatment (the lagged damping changes the trajectory at O(dt zeta) but enters the identity
exactly).  At safety 0.1, runs without hops at n = 2, 3, 4 stay below 2e-4, but from n = 5 on
(and in the paper's hopping runs, D = 0.05 a, from n = 4 on: 2.7e-3, a chaotic defect regime with
the same error) 1e-3 is missed by a factor 2-3.  Hence the solver's default safety is 0.05, where
every run measured closes to <= 8e-4 (paper runs n = 2, 3, 4, 6, 8, 11: 1.4e-7, 6.2e-5, 6.8e-4,
6.7e-4, 8.0e-4, 7.6e-4; D = 0.02 a, n = 5, 6: 5.0e-4, 7.4e-4) and the paper's runs still take
under 1 s.  A shadow-energy correction would hide the error, not remove it; a higher-order
integrator would remove it at several force passes per step and is not done.

Stability with damping.  For one mode of frequency omega and damping ratio zeta the
scheme is stable for omega dt / 2 < sqrt(1 + zeta^2) - zeta.  The radial pair damping is not
proportional to the stiffness, so on small lattices another mode can limit first: at n = 2,
zeta = 0.2 (top mode) a mode at |lambda| = 0.96 omega_max has zeta = 0.29, and the measured limit
0.752 agrees with the spectral radius of the exact linearised one-step map (0.758), not with the
single-mode formula (0.820).  `modal.discrete_stability_limit` computes the former; the solver
guards dt with it and reports both.

Computes: hotness sums (whole window and its two halves), hop events (pairs leaving their root
interval), neighbourhood checks, blow-up checks and a coarse energy history.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .codes import E_START, FREE, FROZEN, GROUP, K_HALF1, K_HALF2, K_HOT_STEPS, PRESCRIBED, RUNNING
from .computes import finish, hop_out, neighbourhood, record, reset_outputs, verdict
from .force import energy_x, force_x
from .kernel_state import FixArrays, LatticeArrays, RunOutputs, RunParams, RunState


@njit(inline="always")
def separation(x, i, j):
    """Vector from particle i to particle j of the (N, 3) positions x, and its length."""
    dx = x[j, 0] - x[i, 0]
    dy = x[j, 1] - x[i, 1]
    dz = x[j, 2] - x[i, 2]
    return dx, dy, dz, math.sqrt(dx * dx + dy * dy + dz * dz)


@njit(inline="always")
def add_pair(f, i, j, g, ex, ey, ez):
    """Pair force g along (ex, ey, ez) added to particle i and subtracted from j."""
    f[i, 0] += g * ex
    f[i, 1] += g * ey
    f[i, 2] += g * ez
    f[j, 0] -= g * ex
    f[j, 1] -= g * ey
    f[j, 2] -= g * ez


@njit(cache=True)
def pair_forces(x, vel, pi, pj, lo, hi, c, a, delta, fc, fd, out, ever, step, counters):
    """Conservative and damping forces of all listed pairs; updates hop flags and counters."""
    fc[:] = 0.0
    fd[:] = 0.0
    inv_a = 1.0 / a
    for k in range(pi.shape[0]):
        i = pi[k]
        j = pj[k]
        dx, dy, dz, r = separation(x, i, j)
        ir = 1.0 / r
        ex = dx * ir
        ey = dy * ir
        ez = dz * ir
        xr = r * inv_a
        add_pair(fc, i, j, force_x(xr, c), ex, ey, ez)
        if delta != 0.0:
            rdot = (vel[j, 0] - vel[i, 0]) * ex + (vel[j, 1] - vel[i, 1]) * ey + (vel[j, 2] - vel[i, 2]) * ez
            add_pair(fd, i, j, delta * rdot, ex, ey, ez)
        if xr < lo[k] or xr >= hi[k]:
            hop_out(k, out, ever, step, counters)
        elif out[k] != 0:
            out[k] = 0


@njit(cache=True)
def potential_energy(x, pi, pj, r0, c, a):
    """U(x) - U(x_rest), summed over listed pairs (J)."""
    u = 0.0
    inv_a = 1.0 / a
    for k in range(pi.shape[0]):
        r = separation(x, pi[k], pj[k])[3]
        u += energy_x(r0[k] * inv_a, r * inv_a, c)
    return u * a


@njit(cache=True)
def _kick(t_next, t_now, dt, x_rest, kind, amp, phase, omega, mass, f, vm, vp, lam, vc, group_mass,
          free_centre, gamma, kt, has_bath):
    """v_{n+1/2} from v_{n-1/2} and F_n for every fix; lambda_n = m (vp - vm)/dt - F_n."""
    n = vm.shape[0]
    gsum0 = 0.0
    gsum1 = 0.0
    gsum2 = 0.0
    if free_centre:
        for i in range(n):
            if kind[i] == GROUP:
                gsum0 += f[i, 0]
                gsum1 += f[i, 1]
                gsum2 += f[i, 2]
        vc[0] += dt * gsum0 / group_mass
        vc[1] += dt * gsum1 / group_mass
        vc[2] += dt * gsum2 / group_mass
    inv_dt = 1.0 / dt
    for i in range(n):
        kd = kind[i]
        if kd == FREE:
            if has_bath and gamma[i] > 0.0:
                damp = math.exp(-gamma[i] * dt)
                sig = math.sqrt(kt[i] / mass * (1.0 - damp * damp))
                for d in range(3):
                    noise = np.random.standard_normal()  # noqa: NPY002 (numba: per-thread RNG seeded in run)
                    vp[i, d] = vm[i, d] * damp + sig * noise + dt * f[i, d] / mass
            else:
                for d in range(3):
                    vp[i, d] = vm[i, d] + dt * f[i, d] / mass
        elif kd == FROZEN:
            for d in range(3):
                vp[i, d] = 0.0
        else:
            s1 = math.sin(omega * t_next + phase[i])
            s0 = math.sin(omega * t_now + phase[i])
            for d in range(3):
                vp[i, d] = amp[i, d] * (s1 - s0) * inv_dt
                if kd == GROUP:
                    vp[i, d] += vc[d]
        for d in range(3):
            lam[i, d] = mass * (vp[i, d] - vm[i, d]) * inv_dt - f[i, d]


@njit(cache=True)
def run(state: RunState, lattice: LatticeArrays, fixes: FixArrays, params: RunParams, out: RunOutputs) -> int:
    """Integrate params.n_steps from t = 0 (state.x: positions at t = 0, overwritten with the final state).

    out.hot (3, N): sums of KE_j * dt over the window [n_start, n_end) and over its two halves.
    out.energy: E_START, E_END (leapfrog energies), E_DISS (>= 0), E_DRIVE, E_BATH (work done on the
    lattice), E_KIN_END, E_POT_END.  out.counters: see K_*; out.history: one row per check.
    out.ever (P,): 1 for pairs that ever left their root interval.
    Stops early (keeping all sums) on NaN, energy growth (kinetic energy above blowup_factor times
    E_start + net work in + e_scale, the energy scale of the drives and baths: the discrete energy
    identity bounds it by the first two), particles leaving the bar or a broken neighbourhood;
    counters[K_STATUS] says which.  Returns the number of history rows written.
    """
    x, v0 = state
    x_rest, mass, a, pi, pj, r0, lo, hi = (lattice.x_rest, lattice.mass, lattice.a, lattice.pi, lattice.pj,
                                           lattice.r0, lattice.lo, lattice.hi)
    kind, amp, phase, gamma, kt, omega, free_centre, seed = fixes
    c, delta, dt, n_steps, n_start, n_end = params.coeffs, params.delta, params.dt, params.n_steps, params.n_start, \
        params.n_end
    hot, energy, counters, history, ever = out
    np.random.seed(seed)  # noqa: NPY002 (numba supports only the legacy seeded RNG in kernels)
    n = x.shape[0]
    npair = pi.shape[0]
    has_bath = False
    for i in range(n):
        if gamma[i] > 0.0:
            has_bath = True
    group_mass = 0.0
    for i in range(n):
        if kind[i] == GROUP:
            group_mass += mass
    if group_mass == 0.0:
        free_centre = False
    fc = np.zeros((n, 3))
    fd = np.zeros((n, 3))
    fc1 = np.zeros((n, 3))
    fd1 = np.zeros((n, 3))
    f = np.zeros((n, 3))
    lam = np.zeros((n, 3))
    lam1 = np.zeros((n, 3))
    vm = np.zeros((n, 3))
    vp = np.zeros((n, 3))
    vc = np.zeros(3)
    cpos = np.zeros(3)
    out = np.zeros(npair, dtype=np.int8)
    reset_outputs(counters, energy)
    n_mid = (n_start + n_end) // 2

    # start: forces at t = 0 with damping from v0, then v_{-1/2} so that v_{+1/2} = v0 + dt/2 a0
    pair_forces(x, v0, pi, pj, lo, hi, c, a, delta, fc, fd, out, ever, 0, counters)
    for i in range(n):
        for d in range(3):
            f[i, d] = fc[i, d] + fd[i, d]
    for i in range(n):
        kd = kind[i]
        if kd == FREE:
            for d in range(3):
                vm[i, d] = v0[i, d] - 0.5 * dt * f[i, d] / mass
        elif kd == FROZEN:
            for d in range(3):
                vm[i, d] = 0.0
        else:
            s1 = math.sin(phase[i])
            s0 = math.sin(-omega * dt + phase[i])
            for d in range(3):
                vm[i, d] = amp[i, d] * (s1 - s0) / dt
    if free_centre:
        gs = np.zeros(3)
        for i in range(n):
            if kind[i] == GROUP:
                for d in range(3):
                    gs[d] += f[i, d]
        for d in range(3):
            vc[d] = -0.5 * dt * gs[d] / group_mass
        for i in range(n):
            if kind[i] == GROUP:
                for d in range(3):
                    vm[i, d] += vc[d]
    _kick(dt, 0.0, dt, x_rest, kind, amp, phase, omega, mass, f, vm, vp, lam, vc, group_mass,
          free_centre, gamma, kt, has_bath)
    e0 = 0.0
    for i in range(n):
        for d in range(3):
            e0 += 0.5 * mass * vm[i, d] * vp[i, d]
    energy[E_START] = e0 + potential_energy(x, pi, pj, r0, c, a)

    diss = w_drive = w_bath = 0.0  # energy dissipated and work done by drives and baths so far
    hrow = step = 0
    status = RUNNING
    while step < n_steps:
        t = step * dt
        # --- computes at time t_n: hotness from v_n = (v_{n-1/2} + v_{n+1/2}) / 2
        if n_start <= step < n_end:
            counters[K_HOT_STEPS] += 1
            half = 1 if step < n_mid else 2
            counters[K_HALF1 if half == 1 else K_HALF2] += 1
            for i in range(n):
                v2 = 0.0
                for d in range(3):
                    vv = 0.5 * (vm[i, d] + vp[i, d])
                    v2 += vv * vv
                e = 0.5 * mass * v2 * dt
                hot[0, i] += e
                hot[half, i] += e
        if step % params.check_every == 0:
            kin = 0.0
            bad = False
            left = False
            for i in range(n):
                for d in range(3):
                    vv = 0.5 * (vm[i, d] + vp[i, d])
                    kin += 0.5 * mass * vv * vv
                    if not (math.isfinite(x[i, d]) and math.isfinite(vv)):
                        bad = True
                    if x[i, d] < params.box_lo[d] or x[i, d] > params.box_hi[d]:
                        left = True
            status = verdict(bad, left, kin, energy[E_START] + w_drive + w_bath, params.blowup_factor,
                             params.e_scale)
            if status == RUNNING:
                status = neighbourhood(x[:, 0], x[:, 1], x[:, 2], x_rest, kind, pi, pj, a, params.cutoff_rest,
                                       params.contact_fraction, params.skin)
            if hrow < history.shape[0]:
                pot = potential_energy(x, pi, pj, r0, c, a) if not bad else np.nan
                record(history, hrow, t, kin, pot, diss, w_drive, w_bath)
                hrow += 1
            if status != RUNNING:
                break
        # --- drift to t_{n+1}
        t1 = t + dt
        if free_centre:
            for d in range(3):
                cpos[d] += dt * vc[d]
        for i in range(n):
            kd = kind[i]
            if kd == FREE:
                for d in range(3):
                    x[i, d] += dt * vp[i, d]
            elif kd != FROZEN:
                s1 = math.sin(omega * t1 + phase[i])
                for d in range(3):
                    x[i, d] = x_rest[i, d] + amp[i, d] * s1
                    if kd == GROUP:
                        x[i, d] += cpos[d]
        # --- forces at t_{n+1}, damping with v_{n+1/2}
        pair_forces(x, vp, pi, pj, lo, hi, c, a, delta, fc1, fd1, out, ever, step + 1, counters)
        for i in range(n):
            for d in range(3):
                f[i, d] = fc1[i, d] + fd1[i, d]
        # --- kick: v_{n+3/2}; vm <- v_{n+1/2}
        vm, vp = vp, vm
        _kick(t1 + dt, t1, dt, x_rest, kind, amp, phase, omega, mass, f, vm, vp, lam1, vc, group_mass,
              free_centre, gamma, kt, has_bath)
        # --- energy bookkeeping over n -> n+1 with v_{n+1/2} (now vm)
        for i in range(n):
            pd = 0.0
            pl = 0.0
            for d in range(3):
                pd += vm[i, d] * (fd[i, d] + fd1[i, d])
                pl += vm[i, d] * (lam[i, d] + lam1[i, d])
            diss -= 0.5 * dt * pd
            kd = kind[i]
            if kd == PRESCRIBED or kd == GROUP:
                w_drive += 0.5 * dt * pl
            elif kd == FREE:
                w_bath += 0.5 * dt * pl
        fd, fd1 = fd1, fd
        fc, fc1 = fc1, fc
        lam, lam1 = lam1, lam
        step += 1

    e1 = 0.0
    kin = 0.0
    for i in range(n):
        for d in range(3):
            e1 += 0.5 * mass * vm[i, d] * vp[i, d]
            vv = 0.5 * (vm[i, d] + vp[i, d])
            kin += 0.5 * mass * vv * vv
    pot = potential_energy(x, pi, pj, r0, c, a)
    finish(counters, energy, step, status, e1 + pot, diss, w_drive, w_bath, kin, pot)
    return hrow
