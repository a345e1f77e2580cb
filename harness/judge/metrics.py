"""Metrics: field errors, observed order, Richardson extrapolation and the GCI.

The lattice family is refined non-uniformly (ratios 1.58, 1.36, ...), so orders are
fitted against h by least squares and the Richardson/GCI step uses the general
three-grid procedure of Celik et al., J. Fluids Eng. 130 (2008) 078001, which
solves for p with unequal ratios r21 != r32.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def field_errors(values: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """L2 (root mean square) and L-infinity error of sampled values against a reference."""
    d = np.asarray(values, dtype=float) - np.asarray(reference, dtype=float)
    if d.size == 0:
        raise ValueError("field_errors: no sample values")
    return {"l2": float(np.sqrt(np.mean(d * d))), "linf": float(np.max(np.abs(d)))}


@dataclass(frozen=True)
class OrderFit:
    """A least-squares fit log err = log C + p log h: the order p, the constant C, the standard error of p
    (nan for two points: a line through two points has no residual to estimate it from) and the h used."""

    order: float
    constant: float
    order_se: float
    h: tuple[float, ...]


def fit_order(h: np.ndarray, err: np.ndarray, finest: int | None = None) -> OrderFit:
    """The order fitted over the `finest` smallest h, with the standard error of the slope from the residuals
    (the textbook s / sqrt(sum (x - mean x)^2) with s^2 = SSR / (m - 2) on m points)."""
    h = np.asarray(h, dtype=float)
    err = np.abs(np.asarray(err, dtype=float))
    order = np.argsort(h)
    if finest is not None:
        order = order[:finest]
    if order.size < 2:
        raise ValueError("observed_order needs at least two points")
    if np.any(err[order] <= 0) or np.any(h[order] <= 0):
        raise ValueError("observed_order needs positive h and errors")
    x, y = np.log(h[order]), np.log(err[order])
    p, logc = np.polyfit(x, y, 1)
    se = math.nan
    if order.size > 2:
        residual = y - (p * x + logc)
        se = float(math.sqrt(float(residual @ residual) / (order.size - 2) / float(((x - x.mean()) ** 2).sum())))
    return OrderFit(float(p), float(math.exp(logc)), se, tuple(float(v) for v in np.sort(h[order])))


def observed_order(h: np.ndarray, err: np.ndarray, finest: int | None = None) -> tuple[float, float]:
    """Least-squares slope p and constant C of log err = log C + p log h over the `finest` smallest h."""
    fit = fit_order(h, err, finest)
    return fit.order, fit.constant


def classify(values: np.ndarray) -> str:
    """Classify a sequence ordered coarse -> fine: monotonic, oscillatory or divergent.

    Uses the ratio R = (f_k - f_{k+1}) / (f_{k-1} - f_k) of successive changes over the three finest
    values (Stern et al. 2001): 0 < R < 1 monotonic, -1 < R < 0 oscillatory, |R| >= 1 divergent.
    A sequence with an exactly zero change is called monotonic (converged to round-off).
    """
    f = np.asarray(values, dtype=float)
    if f.size < 3:
        raise ValueError("classify needs at least three values")
    e32, e21 = f[-2] - f[-3], f[-1] - f[-2]
    if e32 == 0.0 or e21 == 0.0:
        return "monotonic"
    r = e21 / e32
    if abs(r) >= 1.0:
        return "divergent"
    return "monotonic" if r > 0 else "oscillatory"


@dataclass(frozen=True)
class Richardson:
    """Three-grid Richardson extrapolation with the Grid Convergence Index (fine grid)."""

    order: float  # apparent order p
    extrapolated: float  # phi_ext^21
    gci_fine: float  # relative GCI on the finest grid (factor of safety 1.25)
    approx_rel_error: float  # e_a^21
    extrap_rel_error: float  # e_ext^21
    kind: str  # monotonic / oscillatory / divergent

    @property
    def uncertainty(self) -> float:
        """Absolute uncertainty band of the fine value implied by the GCI."""
        return abs(self.gci_fine * self.extrapolated)


def richardson(h: np.ndarray, phi: np.ndarray, safety: float = 1.25, max_iter: int = 200) -> Richardson:
    """Celik et al. (2008) on the three finest grids; h and phi in any order.

    Raises ValueError when the apparent order cannot be defined (e.g. identical values).
    """
    h = np.asarray(h, dtype=float)
    phi = np.asarray(phi, dtype=float)
    idx = np.argsort(h)[:3]
    (h1, h2, h3), (f1, f2, f3) = h[idx], phi[idx]
    r21, r32 = h2 / h1, h3 / h2
    e21, e32 = f2 - f1, f3 - f2
    kind = classify([f3, f2, f1])
    if e21 == 0.0 or e32 == 0.0:
        raise ValueError("richardson: two grids give identical values; the order is undefined")
    s = math.copysign(1.0, e32 / e21)
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    for _ in range(max_iter):
        q = math.log((r21**p - s) / (r32**p - s))
        p_new = abs(math.log(abs(e32 / e21)) + q) / math.log(r21)
        if abs(p_new - p) < 1e-12:
            p = p_new
            break
        p = p_new
    ext = (r21**p * f1 - f2) / (r21**p - 1.0)
    ea = abs((f1 - f2) / f1) if f1 != 0 else abs(f1 - f2)
    eext = abs((ext - f1) / ext) if ext != 0 else abs(ext - f1)
    gci = safety * ea / (r21**p - 1.0)
    return Richardson(float(p), float(ext), float(gci), float(ea), float(eext), kind)
