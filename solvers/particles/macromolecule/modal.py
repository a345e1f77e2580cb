"""Modal analysis of the macromolecule lattice: analytic Hessian, frequencies, damping ratio, step limits.

A pair (i, j), d = x_j - x_i, e = d/r, contributes B = F'(r) e e^T + F(r)/r (I - e e^T) (+B on the (i,i) and
(j,j) blocks, -B on (i,j), (j,i)); at rest F = 0 leaves the F' term, the geometric one keeps the Hessian right
anywhere.  Radial damping delta rdot gives B = delta e e^T.  Held particles are removed from the eigenproblem;
A scales the Hessian linearly, so A = A0 (f_top / f0)^2 hits a target top frequency exactly.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.optimize import brentq

from pcverify.scene import SceneError

from .force import SevenRoot, force_slope_array

DENSE_MAX = 1500  # free DOFs up to which dense eigensolvers are used
Basis = tuple[np.ndarray, np.ndarray, str]  # undamped frequencies, mass-normalised shapes, how they were found


def _assemble(positions: np.ndarray, pairs: np.ndarray, blocks: np.ndarray) -> sp.csr_matrix:
    n3 = 3 * positions.shape[0]
    i, j = pairs[:, 0], pairs[:, 1]
    a, b = np.meshgrid(np.arange(3), np.arange(3), indexing="ij")
    rows, cols, vals = [], [], []
    for (pi, pj, sign) in ((i, i, 1.0), (j, j, 1.0), (i, j, -1.0), (j, i, -1.0)):
        rows.append((3 * pi[:, None, None] + a[None]).ravel())
        cols.append((3 * pj[:, None, None] + b[None]).ravel())
        vals.append(sign * blocks.ravel())
    return sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(n3, n3))


def hessian(positions: np.ndarray, pairs: np.ndarray, model: SevenRoot, a: float) -> sp.csr_matrix:
    """Analytic Hessian (N/m) of the conservative potential at `positions`, all 3N DOFs."""
    d = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    r = np.linalg.norm(d, axis=1)
    e = d / r[:, None]
    f, dfdx = force_slope_array(r / a, model.coeffs())
    ee = e[:, :, None] * e[:, None, :]
    blocks = (dfdx / a)[:, None, None] * ee + (f / r)[:, None, None] * (np.eye(3)[None] - ee)
    return _assemble(positions, pairs, blocks)


def damping_matrix(positions: np.ndarray, pairs: np.ndarray, delta: float) -> sp.csr_matrix:
    """Damping matrix (N s/m) of radial pair damping delta * rdot, all 3N DOFs."""
    d = positions[pairs[:, 1]] - positions[pairs[:, 0]]
    e = d / np.linalg.norm(d, axis=1)[:, None]
    return _assemble(positions, pairs, delta * e[:, :, None] * e[:, None, :])


def free_dofs(free: np.ndarray) -> np.ndarray:
    """DOF indices (3i + c) of the free particles (boolean mask over particles)."""
    idx = np.flatnonzero(free)
    return (3 * idx[:, None] + np.arange(3)[None]).ravel()


def linear_step_limit(K: np.ndarray, C: np.ndarray, omega_max: float, lo: float, hi: float, tol: float) -> float:
    """dt omega_max / 2 at which the spectral radius of the one-step amplification matrix of the
    leapfrog scheme with lagged damping crosses 1; K and C are the free-DOF stiffness and damping
    over the mass (dense).  Bisection on [lo, hi] to `tol`."""
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if step_radius(K, C, 2 * mid / omega_max) > 1 + 1e-9 else (mid, hi)
    return 0.5 * (lo + hi)


def step_radius(K: np.ndarray, C: np.ndarray, dt: float) -> float:
    """Spectral radius of the one-step amplification matrix of x_{n+1} = (2 - dt C - dt^2 K) x_n
    - (1 - dt C) x_{n-1} (mass-scaled K and C, dense): the scheme is stable where it is <= 1."""
    eye = np.eye(K.shape[0])
    amp = np.block([[2 * eye - dt * C - dt * dt * K, -eye + dt * C], [eye, np.zeros_like(eye)]])
    return float(np.abs(sla.eigvals(amp)).max())


def top_modes(K: sp.csr_matrix, mass: float, dofs: np.ndarray, k: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Highest angular frequencies (rad/s, ascending) and mass-normalised shapes of the held lattice: all
    (k=None) or the top k; dense eigh up to DENSE_MAX DOFs, else sparse eigsh."""
    Kf = K[dofs][:, dofs]
    nd = len(dofs)
    if nd <= DENSE_MAX or (k is not None and k >= nd - 1):
        lam, vec = sla.eigh(Kf.toarray())
        if k is not None:
            lam, vec = lam[-k:], vec[:, -k:]
    else:
        v0 = np.random.default_rng(0).standard_normal(nd)  # ARPACK's own start vector depends on earlier calls
        lam, vec = spla.eigsh(Kf.tocsc(), k=k or 24, which="LA", tol=1e-12, v0=v0)
        lam, vec = lam[np.argsort(lam)], vec[:, np.argsort(lam)]
    omega = np.sqrt(np.clip(lam, 0.0, None) / mass)
    return omega, vec / np.sqrt(mass)


def modal_basis(K: sp.csr_matrix, mass: float, dofs: np.ndarray, subspace: int = 48) -> Basis:
    """Undamped basis for the damped top-mode problem: all modes if few DOFs, else the top `subspace`."""
    k = None if len(dofs) <= subspace else subspace
    omega, phi = top_modes(K, mass, dofs, k=k)
    return omega, phi, "exact" if k is None else f"top-{len(omega)}-mode subspace"


def damped_top_mode(basis: Basis, C: sp.csr_matrix, dofs: np.ndarray) -> tuple[float, float, str]:
    """(zeta, |lambda|, method) of the top mode of M x'' + C x' + K x = 0: in state space on the basis of
    `modal_basis` (exact with all modes, else the subspace of the highest ones, which C couples the top mode
    to most); the top mode is the underdamped eigenvalue of largest |lambda|, zeta = -Re(lambda)/|lambda|;
    when no mode oscillates zeta = 1 (critical, the bound of every overdamped mode) and the method says so."""
    omega, phi, method = basis
    Cr = phi.T @ (C[dofs][:, dofs] @ phi)
    zeta, modulus = _damped_top(omega, Cr)
    return zeta, modulus, method if zeta < 1.0 else f"{method}; no mode oscillates (every mode overdamped)"


def _damped_top(omega: np.ndarray, Cr: np.ndarray) -> tuple[float, float]:
    m = len(omega)
    ss = np.zeros((2 * m, 2 * m))
    ss[:m, m:] = np.eye(m)
    ss[m:, :m] = -np.diag(omega**2)
    ss[m:, m:] = -Cr
    lam = sla.eigvals(ss)
    under = lam[lam.imag > 1e-12 * np.abs(lam).max()]
    if under.size == 0:  # overdamped: every eigenvalue real
        return 1.0, float(np.abs(lam).max())
    top = under[np.argmax(np.abs(under))]
    return float(-top.real / abs(top)), float(abs(top))


def delta_for_damping_ratio(basis: Basis, C1: sp.csr_matrix, dofs: np.ndarray, zeta: float) -> float:
    """Pair damping delta (N s/m) giving the top mode the damping ratio `zeta`; C1 is C at delta=1.

    First-order start phi^T C1 phi / (2 omega) for the top mode, then secant on delta.
    """
    if zeta == 0.0:
        return 0.0
    omega, phi, _ = basis
    Cr1 = phi.T @ (C1[dofs][:, dofs] @ phi)
    d0 = zeta / (Cr1[-1, -1] / (2 * omega[-1]))
    f0 = _damped_top(omega, d0 * Cr1)[0] - zeta
    d1 = d0 * zeta / (f0 + zeta)
    for _ in range(50):
        f1 = _damped_top(omega, d1 * Cr1)[0] - zeta
        if abs(f1) <= 1e-12 * zeta or f1 == f0:
            break
        d0, d1, f0 = d1, d1 - f1 * (d1 - d0) / (f1 - f0), f1
    return float(d1)


def discrete_stability_limit(basis: Basis, C: sp.csr_matrix, dofs: np.ndarray, tol: float = 1e-9) -> float:
    """Largest omega_max dt / 2 at which the linearised step x_{n+1} = (2 - dt C - dt^2 K) x_n - (1 - dt C)
    x_{n-1} (mass-scaled) is stable, in the basis of `modal_basis` (K = diag(omega^2), C = phi^T C phi, full
    when the damping is not proportional).  One mode: sqrt(1 + zeta^2) - zeta; non-proportional damping can
    make a lower, more damped mode unstable first (the 16-particle lattice: see the tests)."""
    omega, phi, _ = basis
    elastic = omega > 1e-6 * omega.max()  # rigid-body modes (free lattices): undamped, marginal, never limit dt
    omega, phi = omega[elastic], phi[:, elastic]
    Cr = phi.T @ (C[dofs][:, dofs] @ phi)
    w2 = np.diag(omega**2)
    wmax = float(omega.max())

    def rho(h: float) -> float:
        return step_radius(w2, Cr, 2.0 * h / wmax)

    if rho(1.0) <= 1 + tol:
        return 1.0
    # Brent's method on rho - 1 - tol to 1e-9 in h: ~20 eigenvalue solves (rho is not smooth) for the
    # 31 of a bisection, each solve the costly part.  Bracketed from h = 1e-3, not 0: at dt = 0 the step
    # matrix is defective (double eigenvalue 1) and its computed spectral radius can exceed 1 by more than tol
    lo = 1e-3
    while rho(lo) > 1 + tol:  # heavy damping: the limit is set by the damping, far below 2 / omega_max
        if lo < 1e-9:
            raise SceneError("the pair damping makes the explicit step unstable at every omega_max dt / 2 down to "
                             "1e-9; allowed: a smaller delta or damping_ratio")
        lo /= 10.0
    return float(brentq(lambda h: rho(h) - 1.0 - tol, lo, 1.0, xtol=min(1e-9, 1e-6 * lo)))
