"""Metrics: field errors, observed order, Richardson extrapolation and the GCI.

The lattice family is refined non-uniformly (ratios 1.58, 1.36, ...), so orders are fitted against h by least
squares and the Richardson/GCI step uses the general three-grid procedure of Celik et al., J. Fluids Eng. 130
(2008) 078001, which solves for p with unequal ratios r21 != r32.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import RegularGridInterpolator
from scipy.sparse.linalg import spsolve
from scipy.spatial import cKDTree


def field_errors(values: np.ndarray, reference: np.ndarray) -> dict[str, float]:
    """L2 (root mean square) and L-infinity error of sampled values against a reference: of a scalar per point,
    or of a vector per point (k, 3), by the length of its difference."""
    d = np.asarray(values, dtype=float) - np.asarray(reference, dtype=float)
    if d.size == 0:
        raise ValueError("field_errors: no sample values")
    if d.ndim == 2:
        d = np.linalg.norm(d, axis=1)
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
    """Classify a sequence ordered coarse -> fine by the ratio R = (f_k - f_{k+1}) / (f_{k-1} - f_k) of its three
    finest values (Stern et al. 2001): 0 < R < 1 monotonic (also an exactly zero change: converged to round-off),
    -1 < R < 0 oscillatory, |R| >= 1 divergent."""
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
    kind: str  # monotonic / oscillatory / divergent

    @property
    def uncertainty(self) -> float:
        """Absolute uncertainty band of the fine value implied by the GCI."""
        return abs(self.gci_fine * self.extrapolated)


def richardson(h: np.ndarray, phi: np.ndarray, safety: float = 1.25, max_iter: int = 200) -> Richardson:
    """Celik et al. (2008) on the three finest grids, h and phi in any order; ValueError when the apparent order
    cannot be defined (e.g. identical values)."""
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
    ea = abs((f1 - f2) / f1) if f1 != 0 else abs(f1 - f2)  # e_a^21
    gci = safety * ea / (r21**p - 1.0)
    return Richardson(float(p), float(ext), float(gci), kind)


def on_points(points: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """A sampled field (values at `points`, (k, 3)) taken at the points `at`: the values themselves where every
    point is shared (to 1e-9 of the extent), else interpolation on the tensor grid the points form (a lattice's
    nodes, an edge of nodes; a singleton axis must match exactly): cubic (fourth order, so it stays below a
    second-order scheme's own error) where every axis has four points, else linear.  ValueError when `at` needs
    a value the samples cannot give (points that are neither shared nor on a grid, or outside it)."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    values = np.asarray(values, dtype=float).ravel()
    at = np.asarray(at, dtype=float).reshape(-1, 3)
    scale = max(float(np.ptp(points, axis=0).max()), 1e-300)
    tol = 1e-9 * scale
    distance, index = cKDTree(points).query(at)
    if np.all(distance <= tol):  # nested levels: the values themselves
        return values[index]
    axes = [_distinct(points[:, k], tol) for k in range(3)]
    if math.prod(len(a) for a in axes) != len(points):
        raise ValueError("the finer level's sample points neither contain these points nor form a grid")
    index = tuple(np.clip(np.searchsorted(a, points[:, k] - tol), 0, len(a) - 1) for k, a in enumerate(axes))
    grid = np.full(tuple(len(a) for a in axes), np.nan)
    grid[index] = values
    keep = [k for k, a in enumerate(axes) if len(a) > 1]
    for k, a in enumerate(axes):
        if len(a) == 1 and np.any(np.abs(at[:, k] - a[0]) > tol):
            raise ValueError("points off the finer level's sample line or plane")
    inside = all(np.all((at[:, k] >= axes[k][0] - tol) & (at[:, k] <= axes[k][-1] + tol)) for k in keep)
    if not inside:
        raise ValueError("points outside the finer level's samples")
    squeezed = grid.reshape([len(axes[k]) for k in keep])
    clipped = np.column_stack([np.clip(at[:, k], axes[k][0], axes[k][-1]) for k in keep])
    if not all(len(axes[k]) >= 4 for k in keep):  # a cubic needs four points per axis
        return RegularGridInterpolator([axes[k] for k in keep], squeezed)(clipped)
    return RegularGridInterpolator([axes[k] for k in keep], squeezed, method="cubic", solver=spsolve)(clipped)


def _difference_order(h: np.ndarray, d: np.ndarray, iterations: int = 50) -> tuple[float, float]:
    """(order, its standard error) from successive differences d_k = |u_k - u_k+1| = C h_k^p (1 - r_k^-p),
    r_k = h_k / h_k+1 (h: the levels, one more than d): the slope of log d against log h, refitted with the
    factor log(1 - r^-p) taken out until p settles (the plain slope is biased when the ratios differ)."""
    hk, ratio = h[:-1], h[:-1] / h[1:]
    fit = fit_order(hk, d)
    for _ in range(iterations):
        if not (math.isfinite(fit.order) and fit.order > 0):
            break
        factor = 1.0 - ratio ** (-fit.order)
        if np.any(factor <= 0):
            break
        new = fit_order(hk, d / factor)
        done = abs(new.order - fit.order) < 1e-12
        fit = new
        if done:
            break
    return fit.order, fit.order_se


def _distinct(values: np.ndarray, tol: float) -> np.ndarray:
    """The distinct coordinates among `values` (sorted; values closer than tol are one, the first kept)."""
    v = np.sort(values)
    return v[np.concatenate([[True], np.diff(v) > tol])]


@dataclass(frozen=True)
class SelfConvergence:
    """A solver's field sequence against itself: per level (coarse to fine) its difference from the finest level
    and from the next finer one (nan at the finest), the order fitted on the successive differences (which have
    the order of the error itself: d_k = C h_k^p (1 - r^-p)), and the finest level's grid convergence index
    1.25 d / (r^p - 1), an error band in the field's own units."""

    to_finest: np.ndarray
    to_next: np.ndarray
    order: float
    order_se: float
    gci_fine: float
    monotone: bool
    kind: str = "self"  # or why the sequence is not asymptotic: oscillatory, scattered


SCATTER = 0.1  # a fitted order whose standard error exceeds this share of it is scattered


def self_convergence(h: np.ndarray, fields: list[tuple[np.ndarray, np.ndarray]], norm: str = "l2",
                     finest: int = 4) -> SelfConvergence:
    """Self-convergence of fields sampled at levels of spacing `h` (coarse to fine; `fields`: (points, values)
    per level); `norm` l2 (root mean square) or linf; the order over the `finest` smallest differences.

    Levels whose points do not coincide are compared through the finer level interpolated cubically (`on_points`),
    whose error, of fourth order, stays below a second-order scheme's own.  A sequence whose differences do not
    fall steadily, or whose fitted order scatters (standard error above SCATTER of it), is not in its asymptotic
    range: its GCI takes the safety factor 3 instead of 1.25 and `kind` says why (verdicts on it are at best
    inconclusive)."""
    h = np.asarray(h, dtype=float)
    if len(fields) < 2 or len(h) != len(fields):
        raise ValueError("self-convergence needs two or more levels")

    def distance(k: int, other: int) -> float:
        points, values = fields[k]
        ref = on_points(*fields[other], points)
        return field_errors(values, ref)[norm]

    to_finest = np.array([distance(k, len(fields) - 1) for k in range(len(fields) - 1)] + [math.nan])
    to_next = np.array([distance(k, k + 1) for k in range(len(fields) - 1)] + [math.nan])
    d = to_next[:-1]
    order = order_se = gci = math.nan
    if len(d) >= 2 and np.all(d > 0):
        order, order_se = _difference_order(h[-(finest + 1):], d[-finest:])
        ratio = h[-2] / h[-1]
        if order > 0 and ratio > 1:
            gci = 1.25 * d[-1] / (ratio**order - 1)
    monotone = bool(np.all(np.diff(d[-finest:]) < 0)) if len(d) >= 2 else False
    kind = ("oscillatory" if not monotone else
            "scattered" if not (order > 0 and order_se <= SCATTER * order) else "self")
    if kind != "self":
        gci *= 3.0 / 1.25
    return SelfConvergence(to_finest, to_next, order, order_se, gci, monotone, kind)
