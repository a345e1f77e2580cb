"""Seven-root force characteristic of the macromolecule model (Arinchev): the pair style.

F(r) = A (a/r)^p prod_{i=1..7}(r/a - x_i) STEP(r/a; 2s -> 1, 2 -> 0), F > 0 attraction, F = dU/dr, A a force
scale (N).  Stable roots x = 1, sqrt2, sqrt3, 2 (the simple-cubic shells), one unstable root in each gap at
`unstable_fraction` of it; STEP is MSC.Adams' cubic step h0 + (h1 - h0) D^2 (3 - 2D), D = clamp((x - x0)/(x1 -
x0)).  STEP has zero value and slope at x = 2, so F ~ (r - 2a)^3 there: a pair resting at 2a adds no stiffness.

`pair_force` is the force (the kernel's pair loop and potential energy, the tables); `force_slope_x` its
linearisation (F and dF/dx as a running product and its derivative: the modal analysis and `energy_x`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

STABLE = np.array([1.0, math.sqrt(2.0), math.sqrt(3.0), 2.0])

C_A, C_P, C_PINT, C_X0, C_X1, C_ROOTS = 0, 1, 2, 3, 4, 5  # packed coefficient layout (C_ROOTS: 7 roots)

_GL_X, _GL_W = np.polynomial.legendre.leggauss(12)


@dataclass(frozen=True)
class SevenRoot:
    """Coefficients of the seven-root characteristic (lengths in units of the spacing a)."""

    A: float = 1.0
    p: float = 2.0
    s: float = 0.9
    unstable_fraction: float = 0.5

    def __post_init__(self) -> None:
        if not 0.0 < self.unstable_fraction < 1.0:
            raise ValueError(f"unstable_fraction={self.unstable_fraction!r}; allowed: (0, 1)")
        if not 0.0 < self.s < 1.0:
            raise ValueError(f"s={self.s!r}; allowed: (0, 1)")

    @property
    def roots(self) -> np.ndarray:
        """All seven roots in units of a, ascending: the stable ones and one unstable root in each gap."""
        r = np.empty(7)
        r[0::2] = STABLE
        r[1::2] = STABLE[:-1] + self.unstable_fraction * np.diff(STABLE)
        return r

    def basins(self) -> np.ndarray:
        """(4, 2) root intervals [lo, hi) of each stable root: bounded by the unstable roots."""
        u = self.roots[1::2]
        return np.array([[0.0, u[0]], [u[0], u[1]], [u[1], u[2]], [u[2], np.inf]])

    def coeffs(self) -> np.ndarray:
        """Packed float64 vector for the numba functions (layout C_*; C_PINT: p if a small integer, else -1)."""
        pint = float(self.p) if float(self.p).is_integer() and 0 <= self.p <= 64 else -1.0
        return np.array([self.A, self.p, pint, 2.0 * self.s, 2.0, *self.roots], dtype=np.float64)


@njit(inline="always")
def pair_force(x, ix, r0, r1, r2, r3, r4, r5, r6, amp_a, p, step_lo, inv_w, square, step=True):
    """Conservative pair force (N) at x = r/a, branch-free (the kernel's loops vectorise): the root factors as
    a depth-3 tree with A folded in (no pow; exact near the roots), the envelope ix^2 (ix = a/r) if `square`
    (p = 2) else x^-p, the STEP clamped.  step=False leaves the STEP out (for callers below its start)."""
    prod = (((x - r0) * (x - r1)) * ((x - r2) * (x - r3))) * (((x - r4) * (x - r5)) * ((x - r6) * amp_a))
    env = ix * ix if square else x ** (-p)
    if not step:
        return prod * env
    d = (x - step_lo) * inv_w
    d = d if d > 0.0 else 0.0
    d = d if d < 1.0 else 1.0
    return prod * env * (1.0 - d * d * (3.0 - 2.0 * d))


@njit(cache=True)
def force_slope_x(x: float, c: np.ndarray) -> tuple[float, float]:
    """(F, dF/dx) at reduced distance x; dF/dr = (dF/dx) / a.  F equals `pair_force` to rounding."""
    x1 = c[C_X1]
    if x >= x1:
        return 0.0, 0.0
    prod, dprod = 1.0, 0.0
    for i in range(7):
        t = x - c[C_ROOTS + i]
        dprod = dprod * t + prod
        prod *= t
    pint = c[C_PINT]
    if pint >= 0.0:
        inv = 1.0 / x
        env = 1.0
        for _ in range(int(pint)):
            env *= inv
    else:
        env = x ** (-c[C_P])
    denv = -c[C_P] * env / x
    st, dst = 1.0, 0.0
    x0 = c[C_X0]
    if x > x0:
        w = x1 - x0
        d = (x - x0) / w
        st = 1.0 - d * d * (3.0 - 2.0 * d)
        dst = -6.0 * d * (1.0 - d) / w
    A = c[C_A]
    return A * env * prod * st, A * (denv * prod * st + env * dprod * st + env * prod * dst)


@njit(cache=True)
def _gl(lo: float, hi: float, c: np.ndarray) -> float:
    half, mid, s = 0.5 * (hi - lo), 0.5 * (hi + lo), 0.0
    for k in range(_GL_X.shape[0]):
        s += _GL_W[k] * force_slope_x(mid + half * _GL_X[k], c)[0]
    return s * half


@njit(cache=True)
def energy_x(x_from: float, x_to: float, c: np.ndarray) -> float:
    """Integral of F dx from x_from to x_to (multiply by a for joules).

    12-point Gauss-Legendre on each smooth piece (split at the STEP's start, where F'' jumps).  F in the
    running-product form of `force_slope_x`, with which the shipped ledgers were computed (pair_force's tree
    differs in the last bits, which would move the ledger of runs with pairs across the STEP's start)."""
    if x_to == x_from:
        return 0.0
    lo, hi, sign = (x_from, x_to, 1.0) if x_to > x_from else (x_to, x_from, -1.0)
    hi = min(hi, c[C_X1])
    if lo >= hi:
        return 0.0
    x0 = c[C_X0]
    if lo < x0 < hi:
        return sign * (_gl(lo, x0, c) + _gl(x0, hi, c))
    return sign * _gl(lo, hi, c)


@njit(cache=True)
def force_array(x: np.ndarray, c: np.ndarray) -> np.ndarray:
    """`pair_force` (N) over reduced distances x, with the packed coefficients."""
    out = np.empty(x.shape[0])
    inv_w = 1.0 / (c[C_X1] - c[C_X0])
    for i in range(x.shape[0]):
        out[i] = pair_force(x[i], 1.0 / x[i], c[C_ROOTS], c[C_ROOTS + 1], c[C_ROOTS + 2], c[C_ROOTS + 3],
                            c[C_ROOTS + 4], c[C_ROOTS + 5], c[C_ROOTS + 6], c[C_A], c[C_P], c[C_X0], inv_w,
                            c[C_P] == 2.0)
    return out


@njit(cache=True)
def force_slope_array(x: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`force_slope_x` over reduced distances: (F, dF/dx)."""
    f, df = np.empty(x.shape[0]), np.empty(x.shape[0])
    for i in range(x.shape[0]):
        f[i], df[i] = force_slope_x(x[i], c)
    return f, df
