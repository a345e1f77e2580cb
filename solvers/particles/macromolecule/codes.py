"""Codes shared by every kernel of the macromolecule model: fix kinds, run status, output slots.

One set for the fixed-pair-list kernels (reference, fast, fastmath), the large-N kernel and its
ensemble, and the Python code that reads their outputs.

Fix kinds (what a particle's motion is; LAMMPS "fixes"):
  FREE        Newton, optionally with a Langevin bath (gamma, kT);
  FROZEN      held at rest, x = x_rest, v = 0;
  PRESCRIBED  kinematic drive x = x_rest + amp sin(omega t + phase);
  GROUP       one rigid side of the red pair whose relative motion is prescribed (fixed-list kernels
              only: the large-N kernel takes FREE, FROZEN and PRESCRIBED).
"""

from __future__ import annotations

FREE, FROZEN, PRESCRIBED, GROUP = 0, 1, 2, 3
KIND_NAMES = {FREE: "free", FROZEN: "frozen", PRESCRIBED: "prescribed", GROUP: "group"}

# status of a run; RUNNING while a kernel integrates, EXPIRED when the large-N kernel's neighbour
# list must be rebuilt before it can go on
RUNNING, DONE, NAN, GROWTH, LEFT_BAR, ISOLATED, CONTACT, EXPIRED = -1, 0, 1, 2, 3, 4, 5, 6
STATUS_TEXT = {
    DONE: "completed",
    NAN: "NaN/Inf in the state",
    GROWTH: "energy grew beyond blowup_factor times the energy supplied",
    LEFT_BAR: "a particle left the bar's neighbourhood (more than a outside the box)",
    ISOLATED: "broken neighbourhood: a particle is beyond 2a of all its listed neighbours",
    CONTACT: "broken neighbourhood: two unlisted particles came closer than contact_fraction * a",
    EXPIRED: "the neighbour list expired (a particle moved more than skin/2): rebuild and resume",
}

# energy output slots of the fixed-list kernels
E_START, E_END, E_DISS, E_DRIVE, E_BATH, E_KIN_END, E_POT_END = range(7)
N_ENERGY = 8
# counter output slots
K_STEPS, K_HOP_EVENTS, K_HOP_PAIRS, K_FIRST_HOP, K_STATUS, K_STOP_STEP, K_HOT_STEPS, K_HALF1, K_HALF2 = range(9)
N_COUNTERS = 9
# columns of the coarse energy history
H_T, H_KIN, H_POT, H_DISS, H_DRIVE, H_BATH = range(6)
N_HISTORY_COLUMNS = 6
