"""The Fourier series of `bar-heat-faces` written out on its own, a cross-check of the heat family's slab (tests only):
face z=0 at t_max, z=L at 0 K, others insulated.

The field depends on z only.  Steady: T = t_max (1 - z/L).  Transient from T = 0 at t = 0
(the faces switched on at t = 0+), by separation of variables:

    T(z, t) = t_max (1 - z/L) - sum_k (2 t_max / (k pi)) sin(k pi z / L) exp(-alpha k^2 pi^2 t / L^2)

The series is summed until the bound on its tail is below `tol` * t_max.
"""

from __future__ import annotations

import math

import numpy as np


def steady(z: np.ndarray, length: float, t_max: float) -> np.ndarray:
    """Steady linear profile T(z)."""
    return t_max * (1.0 - np.asarray(z, dtype=float) / length)


def terms_needed(t: float, length: float, alpha: float, tol: float = 1e-12) -> int:
    """Number of series terms K such that the tail sum_{k>K} (2/(k pi)) e^{-c k^2} < tol (c = alpha pi^2 t / L^2)."""
    if t <= 0:
        raise ValueError(f"t={t!r} is out of range; allowed: number in (0, inf) s (no convergence at t=0)")
    c = alpha * math.pi**2 * t / length**2
    k = 1
    # tail <= (2 / (k pi)) e^{-c (k+1)^2} / (1 - e^{-c (2k + 3)}), a geometric bound
    while True:
        tail = 2.0 / (k * math.pi) * math.exp(-c * (k + 1) ** 2) / (1.0 - math.exp(-c * (2 * k + 3)))
        if tail < tol:
            return k
        k += 1


def transient(z: np.ndarray, t: float, length: float, alpha: float, t_max: float, tol: float = 1e-12) -> np.ndarray:
    """Temperature T(z, t) of the face-heated bar, accurate to tol * t_max."""
    z = np.asarray(z, dtype=float)
    kmax = terms_needed(t, length, alpha, tol)
    k = np.arange(1, kmax + 1, dtype=float)
    decay = np.exp(-alpha * (k * math.pi / length) ** 2 * t) * 2.0 / (k * math.pi)
    series = np.sin(np.multiply.outer(z, k) * math.pi / length) @ decay
    return t_max * (1.0 - z / length - series)
