"""The energy balance of a run, written once for every particle solver: how far the energy a run holds
drifts from the work done on it, relative to a scale the solver names (its normalisation)."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike


def balance_error(stored: ArrayLike, work: Sequence[ArrayLike], normalisation: float) -> float:
    """max |stored - work[0] - work[1] - ...| / normalisation; NaN when the normalisation is 0.

    `stored` is the change since the start of what the run holds or lost (kinetic + potential energy minus
    their initial value, plus what damping and friction dissipated), a number or a history over time;
    `work` the work done on the run since the start, one term per source (supports, drives, baths, loads),
    subtracted in the order given.  An exact integrator gives 0.  The normalisation makes the error a
    fraction, and each solver reports a different one (different quantities, kept apart):
    - largest energy flow (macromolecule, `simulate.energy_balance_error`): max(|E_start|, |E_end|,
      |W_drive|, |W_bath|, dissipated, 1e-300), the largest energy that was held, came in or went out;
    - peak elastic energy (MCA fracture, `energy_error` of the elastic phase; damped, it is the loss):
      max(max U, 1e-300), the strain energy the loading stored before the first link broke;
    - window work (MCA sliding contact, `energy_balance_error`): |work of the drive and the load over the
      sliding window|, the energy put in while sliding (0 when nothing was: NaN).
    """
    if normalisation == 0:
        return math.nan
    residual = stored
    for term in work:
        residual = residual - term
    return float(np.max(np.abs(residual)) / normalisation)
