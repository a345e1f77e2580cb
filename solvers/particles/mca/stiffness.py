"""Linearised MCA: the stiffness and mass matrices of the automata about the rest state.

The elastic MCA kernel (kernel.py) derives from the potential
    U = sum_p [ kn S (n.du)^2 / (2 r0) + G S |P delta|^2 / r0 + krot G S r0 |phi_j - phi_i|^2 / 2 ]
        + sum_i lam Omega_i theta_i^2 / 2,
    delta = u_j - u_i - q (phi_i + phi_j) x n,   theta_i = sum_j S (n.(u_j - u_i)) / (2 Omega_i),
(P = I - n n, q = r0 / 2) to first order in the displacements u and rotations phi.  Its Hessian K and the
diagonal mass matrix M (m for translations, J for rotations) give the eigenfrequencies (bar-modes) and
the stable time step: velocity Verlet needs dt < 2 / omega_max, and the Gershgorin bound on
M^-1/2 K M^-1/2 bounds omega_max from above.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from .automata import Automata


def _cross_matrix(n: np.ndarray) -> np.ndarray:
    """[n]x for each row of n (P, 3): [n]x a = n x a."""
    z = np.zeros(n.shape[0])
    return np.stack([np.stack([z, -n[:, 2], n[:, 1]], 1), np.stack([n[:, 2], z, -n[:, 0]], 1),
                     np.stack([-n[:, 1], n[:, 0], z], 1)], 1)


def stiffness(aut: Automata, g_mod: float, lam: float, kn: float, krot: float = 0.0,
              rotations: bool = True) -> sp.csr_matrix:
    """Sparse K (6N x 6N with rotations, else 3N x 3N: rotations held at zero)."""
    pos = aut.positions
    pi, pj = aut.pairs[:, 0], aut.pairs[:, 1]
    d = pos[pj] - pos[pi]
    n = d / np.linalg.norm(d, axis=1)[:, None]
    npair = len(pi)
    S, r0 = aut.area, aut.r0
    q = 0.5 * r0
    nd = 6 if rotations else 3
    eye = np.broadcast_to(np.eye(3), (npair, 3, 3))
    proj = eye - n[:, :, None] * n[:, None, :]
    cx = _cross_matrix(n)
    zero = np.zeros((npair, 3, 3))
    # B matrices acting on (u_i, phi_i, u_j, phi_j)
    bn = np.concatenate([-n, np.zeros((npair, 3)), n, np.zeros((npair, 3))], axis=1)[:, None, :]
    bt = np.concatenate([-proj, q[:, None, None] * cx, proj, q[:, None, None] * cx], axis=2)
    br = np.concatenate([zero, -eye, zero, eye], axis=2)
    kp = (kn * S / r0)[:, None, None] * np.einsum("pai,paj->pij", bn, bn)
    kp += (2.0 * g_mod * S / r0)[:, None, None] * np.einsum("pai,paj->pij", bt, bt)
    if krot > 0:
        kp += (krot * g_mod * S * r0)[:, None, None] * np.einsum("pai,paj->pij", br, br)
    keep = np.r_[0:3, 6:9] if not rotations else np.arange(12)
    kp = kp[:, keep][:, :, keep]
    loc = np.arange(nd)
    dofs = np.concatenate([pi[:, None] * nd + loc, pj[:, None] * nd + loc], axis=1)
    rows = np.repeat(dofs, dofs.shape[1], axis=1).ravel()
    cols = np.tile(dofs, (1, dofs.shape[1])).ravel()
    size = nd * aut.size
    k = sp.coo_matrix((kp.ravel(), (rows, cols)), shape=(size, size)).tocsr()
    if lam != 0.0:
        vol = aut.volume
        r_idx = np.concatenate([np.repeat(pi, 6), np.repeat(pj, 6)])
        c_u = np.concatenate([pi[:, None] * nd + np.arange(3), pj[:, None] * nd + np.arange(3)], axis=1)
        vals_i = np.concatenate([-n, n], axis=1) * (S / (2 * vol[pi]))[:, None]
        vals_j = np.concatenate([-n, n], axis=1) * (S / (2 * vol[pj]))[:, None]
        b = sp.coo_matrix((np.concatenate([vals_i.ravel(), vals_j.ravel()]),
                           (r_idx, np.concatenate([c_u.ravel(), c_u.ravel()]))), shape=(aut.size, size)).tocsr()
        k = k + (b.T @ sp.diags(lam * vol) @ b).tocsr()
    return k


def mass_diagonal(aut: Automata, rotations: bool = True) -> np.ndarray:
    """Diagonal of M: (m, m, m, J, J, J) per automaton (or (m, m, m) without rotations)."""
    cols = [aut.mass] * 3 + ([aut.inertia] * 3 if rotations else [])
    return np.stack(cols, axis=1).ravel()


def omega_max_bound(k: sp.csr_matrix, m: np.ndarray) -> float:
    """Gershgorin upper bound of the largest angular frequency of K phi = omega^2 M phi."""
    s = 1.0 / np.sqrt(m)
    a = abs(sp.diags(s) @ k @ sp.diags(s))
    return float(np.sqrt(np.asarray(a.sum(axis=1)).max()))
