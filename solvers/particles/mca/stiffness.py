"""Linearised MCA: the stiffness and mass matrices of the automata about the rest state.

The Hessian of the elastic kernel's potential (wall bonds of the "cells" packing included) and the diagonal mass
matrix give the eigenfrequencies (bar-modes) and, by a Gershgorin bound on omega_max, the stable time step of
velocity Verlet (docs/physics.md, "The MCA solver in detail", "The linearised model").
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


Walls = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]  # automaton, outward normal (k, 3), area, frictionless


def stiffness(aut: Automata, g_mod: float, lam: float, kn: float, krot: float = 0.0,
              rotations: bool = True, walls: Walls | None = None) -> sp.csr_matrix:
    """Sparse K (6N x 6N with rotations, else 3N x 3N: rotations held at zero); with `walls` (k bonds) the
    wall points' degrees of freedom follow the automata's: 6 (N + k) x 6 (N + k)."""
    pos = aut.positions
    pi, pj = aut.pairs[:, 0], aut.pairs[:, 1]
    d = pos[pj] - pos[pi]
    n = d / np.linalg.norm(d, axis=1)[:, None]
    S, r0 = aut.area, aut.r0
    qi = qj = 0.5 * r0
    wi = np.zeros(0, dtype=np.int64) if walls is None else walls[0]
    slide = np.zeros(len(pi), dtype=bool)
    if wi.size:  # a wall bond: a pair (i, wall point) of length a/2, the contact point on the face
        arm = 0.5 * aut.spacing[np.argmax(np.abs(walls[1]), axis=1)]
        pi, pj = np.concatenate([pi, wi]), np.concatenate([pj, aut.size + np.arange(wi.size)])
        n, S = np.concatenate([n, walls[1]]), np.concatenate([S, walls[2]])
        r0, qi, qj = np.concatenate([r0, arm]), np.concatenate([qi, arm]), np.concatenate([qj, 0.0 * arm])
        slide = np.concatenate([slide, np.asarray(walls[3], dtype=bool)])
    wall = np.r_[np.zeros(len(aut.pairs), dtype=bool), np.ones(wi.size, dtype=bool)]
    shear = np.where(slide, 0.0, 1.0)  # a frictionless wall carries no tangential force or moment
    npair = len(pi)
    nd = 6 if rotations else 3
    eye = np.broadcast_to(np.eye(3), (npair, 3, 3))
    proj = eye - n[:, :, None] * n[:, None, :]
    cx = _cross_matrix(n)
    zero = np.zeros((npair, 3, 3))
    # B matrices acting on (u_i, phi_i, u_j, phi_j)
    bn = np.concatenate([-n, np.zeros((npair, 3)), n, np.zeros((npair, 3))], axis=1)[:, None, :]
    bt = np.concatenate([-proj, qi[:, None, None] * cx, proj, qj[:, None, None] * cx], axis=2)
    br = np.concatenate([zero, -eye, zero, eye], axis=2)
    kp = (kn * S / r0)[:, None, None] * np.einsum("pai,paj->pij", bn, bn)
    kp += (shear * 2.0 * g_mod * S / r0)[:, None, None] * np.einsum("pai,paj->pij", bt, bt)
    if krot > 0:
        kp += (shear * krot * g_mod * S * np.where(wall, 2.0 * r0, r0))[:, None, None] * np.einsum("pai,paj->pij",
                                                                                                  br, br)
    keep = np.r_[0:3, 6:9] if not rotations else np.arange(12)
    kp = kp[:, keep][:, :, keep]
    loc = np.arange(nd)
    dofs = np.concatenate([pi[:, None] * nd + loc, pj[:, None] * nd + loc], axis=1)
    rows = np.repeat(dofs, dofs.shape[1], axis=1).ravel()
    cols = np.tile(dofs, (1, dofs.shape[1])).ravel()
    size = nd * (aut.size + wi.size)
    k = sp.coo_matrix((kp.ravel(), (rows, cols)), shape=(size, size)).tocsr()
    if lam != 0.0:
        vol = np.r_[aut.many_body_volume(lam, kn), np.ones(wi.size)]  # the wall points: no many-body term
        r_idx = np.concatenate([np.repeat(pi, 6), np.repeat(pj, 6)])
        c_u = np.concatenate([pi[:, None] * nd + np.arange(3), pj[:, None] * nd + np.arange(3)], axis=1)
        side = np.where(wall, 1.0, 0.5)  # a wall bond's elongation is all automaton i's
        vals_i = np.concatenate([-n, n], axis=1) * (side * S / vol[pi])[:, None]
        vals_j = np.concatenate([-n, n], axis=1) * (S / (2 * vol[pj]) * ~wall)[:, None]
        b = sp.coo_matrix((np.concatenate([vals_i.ravel(), vals_j.ravel()]),
                           (r_idx, np.concatenate([c_u.ravel(), c_u.ravel()]))),
                          shape=(aut.size + wi.size, size)).tocsr()
        k = k + (b.T @ sp.diags(lam * vol * np.r_[np.ones(aut.size), np.zeros(wi.size)]) @ b).tocsr()
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
