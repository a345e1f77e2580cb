"""The bar's spring lattice, built with numpy: simple-cubic nodes at spacing a = W/(n - 1) (the MCA's "nodes"
packing), central springs to the 6 axis and 12 face-diagonal neighbours.

Stiffness.  A pair lattice with axis springs k1 and face-diagonal springs k2 on a cubic cell of side a has
C11 = (k1 + 2 k2)/a, C12 = C44 = k2/a (the Cauchy relation of central forces); isotropy (C11 - C12 = 2 C44)
needs k1 = k2 = k, and then lambda = mu = k/a: nu = 1/4 whatever k, E = 5k/(2a), so k = 2 E a / 5.  Each spring
is shared by the cubic cells that hold it (4 for an axis edge, 2 for a face diagonal); at the bar's faces and
edges fewer cells hold it and its stiffness is k times that share, so a uniform strain is an exact equilibrium
of the finite bar (no surface layer) and E_eff = E up to geometric nonlinearity.  Node masses: rho times the
node's share of the cells (a^3, halved on each face it lies on).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

AXES = ((1, 0, 0), (0, 1, 0), (0, 0, 1))
DIAGONALS = ((1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1))
CELLS_IN_BULK = {1: 4, 2: 2}  # cells holding an axis edge, a face diagonal


@dataclass(frozen=True)
class Lattice:
    """Nodes (positions, masses) and springs (i, j, stiffness, rest length, family: 0 axis, 1 diagonal; axis:
    the spring's direction index 0, 1, 2 for axis springs, -1 for diagonals; plane: the normal of a diagonal's
    plane 0, 1, 2, -1 for axis springs)."""

    shape: tuple[int, int, int]
    spacing: float
    positions: np.ndarray
    mass: np.ndarray
    i: np.ndarray
    j: np.ndarray
    k: np.ndarray
    r0: np.ndarray
    family: np.ndarray
    axis: np.ndarray
    plane: np.ndarray

    @property
    def size(self) -> int:
        return int(self.positions.shape[0])

    def on_face(self, face: str, extent: np.ndarray) -> np.ndarray:
        """Indices of the nodes on `face` ("x0", "zL", ...)."""
        ax = "xyz".index(face[0])
        target = 0.0 if face[1:] == "0" else float(extent[ax])
        return np.flatnonzero(np.abs(self.positions[:, ax] - target) <= 1e-9 * float(extent[ax]))


def bar_lattice(extent: np.ndarray, n: int, youngs: float, density: float) -> Lattice:
    """The lattice of a W x H x L bar at n nodes across the width (spring constant k = 2 E a / 5)."""
    a = float(extent[0]) / (n - 1)
    shape = tuple(int(round(float(e) / a)) + 1 for e in extent)
    grid = np.stack(np.meshgrid(*[np.arange(s) for s in shape], indexing="ij"), axis=-1).reshape(-1, 3)
    index = np.arange(grid.shape[0]).reshape(shape)
    boundary = (grid == 0) | (grid == np.array(shape) - 1)
    mass = density * a**3 * np.prod(np.where(boundary, 0.5, 1.0), axis=1)
    k = 0.4 * youngs * a
    parts = []
    for offset in (*AXES, *DIAGONALS):
        d = np.array(offset)
        other = grid + d
        ok = np.all((other >= 0) & (other < np.array(shape)), axis=1)
        lo, hi = grid[ok], other[ok]
        corner = np.minimum(lo, hi)
        cells = np.ones(lo.shape[0])
        for ax in np.flatnonzero(d == 0):  # cells on either side along the axes the spring does not span
            cells = cells * ((corner[:, ax] >= 1).astype(float) + (corner[:, ax] <= shape[ax] - 2).astype(float))
        nz = int(np.count_nonzero(d))
        fam = 0 if nz == 1 else 1
        parts.append((index[tuple(lo.T)], index[tuple(hi.T)], k * cells / CELLS_IN_BULK[nz],
                      np.full(lo.shape[0], a * np.sqrt(nz)), np.full(lo.shape[0], fam),
                      np.full(lo.shape[0], int(np.argmax(d != 0)) if nz == 1 else -1),
                      np.full(lo.shape[0], int(np.argmax(d == 0)) if nz == 2 else -1)))
    i, j, kk, r0, fam, axis, plane = (np.concatenate(c) for c in zip(*parts, strict=True))
    return Lattice(shape=shape, spacing=a, positions=grid * a, mass=mass, i=i, j=j, k=kk, r0=r0, family=fam,
                   axis=axis, plane=plane)


def gershgorin_omega(lat: Lattice) -> float:
    """An upper bound of the network's highest angular frequency: max over rows of sum |K_row| / m."""
    d = lat.positions[lat.j] - lat.positions[lat.i]
    e = np.abs(d / np.linalg.norm(d, axis=1)[:, None])
    row = 2.0 * lat.k[:, None] * e * e.sum(axis=1)[:, None]  # |diagonal block| + |off-diagonal block| per dof
    total = np.zeros((lat.size, 3))
    np.add.at(total, lat.i, row)
    np.add.at(total, lat.j, row)
    return float(np.sqrt((total / lat.mass[:, None]).max()))
