"""Codes of the macromolecule kernel and the Python code that reads its outputs: fix kinds, run status,
output slots.

Fix kinds (what a particle's motion is; LAMMPS "fixes"): FREE (Newton, optionally a Langevin bath),
FROZEN (held at rest), PRESCRIBED (kinematic drive x = x_rest + amp sin(omega t + phase)), GROUP (one
rigid side of the red pair whose relative motion is prescribed).
"""

from __future__ import annotations

FREE, FROZEN, PRESCRIBED, GROUP = 0, 1, 2, 3

RUNNING, DONE, NAN, GROWTH, LEFT_BAR, ISOLATED, CONTACT = -1, 0, 1, 2, 3, 4, 5  # RUNNING while integrating
STATUS_TEXT = {
    DONE: "completed",
    NAN: "NaN/Inf in the state",
    GROWTH: "energy grew beyond blowup_factor times the energy supplied",
    LEFT_BAR: "a particle left the bar's neighbourhood (more than a outside the box)",
    ISOLATED: "broken neighbourhood: a particle is beyond 2a of all its listed neighbours",
    CONTACT: "broken neighbourhood: two unlisted particles came closer than contact_fraction * a",
}

E_START, E_END, E_DISS, E_DRIVE, E_BATH, E_KIN_END, E_POT_END = range(7)  # energy output slots
K_STEPS, K_HOP_EVENTS, K_HOP_PAIRS, K_FIRST_HOP, K_STATUS, K_STOP_STEP, K_HOT_STEPS, K_HALF1, K_HALF2 = range(9)
K_STATIONARY = 9  # the step at which a run with a stationarity stop ended stationary (-1: it did not)
H_T, H_KIN, H_POT, H_DISS, H_DRIVE, H_BATH = range(6)  # columns of the coarse energy history
N_ENERGY, N_COUNTERS, N_HISTORY_COLUMNS = 8, 10, 6  # sizes of the outputs (energy, counters, history rows)
