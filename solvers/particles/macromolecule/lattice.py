"""The particle lattice of the macromolecule model: nodes (`Box.lattice_points`, x slowest, z fastest; spacing
a = W/(n-1)), masses rho V / N and the fixed pair list: every pair with rest distance r0 <= 2a (shells a, sqrt2 a,
sqrt3 a, 2a).  Pairs at exactly 2a carry no force or stiffness at rest but are kept ("keep"): the paper makes
every pair closer than 2a interact, so a compressed 2a pair feels the repulsion, and every listed pair carries
the radial damping.  "drop" removes them (26 instead of 32 neighbours) for comparison.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from pcverify.scene import Box, SceneError

from .force import STABLE

REL_TOL = 1e-9


@dataclass(frozen=True, eq=False)
class Lattice:
    """Rest positions (N, 3), spacing, particle mass, pairs (P, 2) and their rest shells."""

    n: int
    a: float
    positions: np.ndarray
    mass: float
    pairs: np.ndarray
    r0: np.ndarray
    shell: np.ndarray  # index of the stable root the pair rests at: 0..3 for a, sqrt2 a, sqrt3 a, 2a
    shape: tuple[int, int, int]  # nodes per axis

    @property
    def size(self) -> int:
        return int(self.positions.shape[0])

    def node_at(self, points: np.ndarray) -> np.ndarray:
        """Indices of the nodes at `points` (k, 3); SceneError if a point is not a node."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        dist, idx = cKDTree(self.positions).query(pts)
        bad = np.flatnonzero(dist > 1e-6 * self.a)
        if bad.size:
            raise SceneError(
                f"sample point {pts[bad[0]].tolist()} is not a lattice node of n={self.n}; the macromolecule "
                "solver reports at its particles only"
            )
        return idx.astype(np.int64)

    def within(self, centre: np.ndarray, radius: float) -> np.ndarray:
        """Indices of nodes within `radius` of `centre` (inclusive to a relative 1e-9)."""
        d = np.linalg.norm(self.positions - np.asarray(centre, dtype=float), axis=1)
        return np.flatnonzero(d <= radius * (1 + REL_TOL) + 1e-12 * self.a)


def build_lattice(box: Box, n: int, density: float, pairs_at_2a: str = "keep") -> Lattice:
    """Lattice of resolution n with its fixed pair list (see the module docstring for 2a pairs)."""
    if pairs_at_2a not in ("keep", "drop"):
        raise SceneError(f"pairs_at_2a={pairs_at_2a!r} is not allowed; allowed: keep, drop")
    pos = box.lattice_points(n)
    a = box.lattice_spacing(n)
    mass = density * box.volume / pos.shape[0]
    pairs = cKDTree(pos).query_pairs(2.0 * a * (1 + REL_TOL), output_type="ndarray").astype(np.int64)
    pairs = np.sort(pairs, axis=1)
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    r0 = np.linalg.norm(pos[pairs[:, 1]] - pos[pairs[:, 0]], axis=1)
    shell = np.argmin(np.abs(r0[:, None] / a - STABLE[None, :]), axis=1).astype(np.int64)
    if pairs_at_2a == "drop":
        keep = shell < 3
        pairs, r0, shell = pairs[keep], r0[keep], shell[keep]
    return Lattice(n=n, a=a, positions=pos, mass=mass, pairs=pairs, r0=r0, shell=shell, shape=box.lattice_shape(n))
