"""Computes of the fixed-pair-list kernels (LAMMPS' word for measurements): hop events, blow-up and
neighbourhood checks, the energy history and the run's final counters.  Shared by the reference and
the fast kernel, so that both judge a run by the same rules."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .codes import (
    CONTACT,
    DONE,
    E_BATH,
    E_DISS,
    E_DRIVE,
    E_END,
    E_KIN_END,
    E_POT_END,
    FROZEN,
    GROWTH,
    H_BATH,
    H_DISS,
    H_DRIVE,
    H_KIN,
    H_POT,
    H_T,
    ISOLATED,
    K_FIRST_HOP,
    K_HOP_EVENTS,
    K_HOP_PAIRS,
    K_STATUS,
    K_STEPS,
    K_STOP_STEP,
    LEFT_BAR,
    NAN,
    RUNNING,
)


@njit(inline="always")
def hop_out(k, out, ever, step, counters):
    """Pair k is outside its root interval: an event if it was inside, its first exit, the first step.

    (The caller tests the interval and clears out[k] when inside: a flag passed in here instead
    costs the reference kernel 30 % in the pair loop.)"""
    if out[k] == 0:
        out[k] = 1
        counters[K_HOP_EVENTS] += 1
        if ever[k] == 0:
            ever[k] = 1
            counters[K_HOP_PAIRS] += 1
            if counters[K_FIRST_HOP] < 0:
                counters[K_FIRST_HOP] = step


@njit(inline="always")
def reset_outputs(counters, energy):
    """Counters and energies of a run before its first step (no hop yet, running)."""
    for k in range(counters.shape[0]):
        counters[k] = 0
    counters[K_FIRST_HOP] = -1
    counters[K_STATUS] = RUNNING
    energy[:] = 0.0


@njit(inline="always")
def verdict(bad, left, kin, supplied, blowup_factor, e_scale):
    """Status of a check from the state alone: NaN, left the bar, energy growth, else RUNNING."""
    if bad:
        return NAN
    if left:
        return LEFT_BAR
    if kin > blowup_factor * (max(supplied, 0.0) + e_scale):
        return GROWTH
    return RUNNING


@njit(inline="always")
def record(history, hrow, t, kin, pot, diss, w_drive, w_bath):
    """One row of the coarse energy history."""
    history[hrow, H_T] = t
    history[hrow, H_KIN] = kin
    history[hrow, H_POT] = pot
    history[hrow, H_DISS] = diss
    history[hrow, H_DRIVE] = w_drive
    history[hrow, H_BATH] = w_bath


@njit(inline="always")
def finish(counters, energy, step, status, e_end, diss, w_drive, w_bath, kin_end, pot_end):
    """Counters and energies of a run that stopped at `step` with `status` (RUNNING: completed)."""
    counters[K_STEPS] = step
    counters[K_STOP_STEP] = step
    counters[K_STATUS] = DONE if status == RUNNING else status
    energy[E_END] = e_end
    energy[E_DISS] = diss
    energy[E_DRIVE] = w_drive
    energy[E_BATH] = w_bath
    energy[E_KIN_END] = kin_end
    energy[E_POT_END] = pot_end


@njit(cache=True)
def neighbourhood(px, py, pz, x_rest, kind, pi, pj, a, cutoff_rest, contact_fraction, skin):
    """ISOLATED / CONTACT check of the fixed pair list (positions as x, y, z vectors); RUNNING if fine."""
    n = px.shape[0]
    near = np.full(n, np.inf)
    for k in range(pi.shape[0]):
        i = pi[k]
        j = pj[k]
        dx = px[j] - px[i]
        dy = py[j] - py[i]
        dz = pz[j] - pz[i]
        r = math.sqrt(dx * dx + dy * dy + dz * dz)
        near[i] = min(near[i], r)
        near[j] = min(near[j], r)
    for i in range(n):
        if kind[i] != FROZEN and near[i] > 2.0 * a:
            return ISOLATED
    # unlisted pairs: only possible when some particle moved more than the skin
    dmax2 = 0.0
    for i in range(n):
        dx = px[i] - x_rest[i, 0]
        dy = py[i] - x_rest[i, 1]
        dz = pz[i] - x_rest[i, 2]
        dmax2 = max(dmax2, dx * dx + dy * dy + dz * dz)
    if 4.0 * dmax2 < skin * skin:
        return RUNNING
    lim2 = (contact_fraction * a) ** 2
    cut2 = cutoff_rest * cutoff_rest
    for i in range(n):
        for j in range(i + 1, n):
            rx = x_rest[j, 0] - x_rest[i, 0]
            ry = x_rest[j, 1] - x_rest[i, 1]
            rz = x_rest[j, 2] - x_rest[i, 2]
            if rx * rx + ry * ry + rz * rz <= cut2:
                continue
            dx = px[j] - px[i]
            dy = py[j] - py[i]
            dz = pz[j] - pz[i]
            if dx * dx + dy * dy + dz * dz < lim2:
                return CONTACT
    return RUNNING

