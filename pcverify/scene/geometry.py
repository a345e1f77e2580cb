"""Geometry of a scene: the box, its lattice family and a resolution.

The box is W x H x L (x across, y vertical, z along).  Resolution n names the simple-cubic lattice
with one spacing a = W / (n - 1) in every direction and nodes on the faces, edges and corners, so
the box must be a whole number of spacings along y and z: (n - 1) H / W and (n - 1) L / W integers.
The paper's bar (0.01 x 0.01 x 0.03 m) gives n x n x (3n - 2) nodes.  Every solver reports at these
nodes and uses h = a / refine, so the same resolution means the same h and node count everywhere.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .params import SceneError, is_real, shown

WHOLE = 1e-9  # relative tolerance of "a whole number of spacings"
# The box's dimensions, m.  Below a micrometre the continuum models stop describing the body (phonon mean free
# paths in metals are 10-100 nm, grains and the automata of MCA are larger still), and with n and refine up to
# 1000 a grid spacing stays above 1e-12 m, so the conductances (k h), penalties (k / h^2) and stiffnesses of
# every solver stay far inside double precision (a 1e-300 m box made FiPy's matrix exactly singular).  Above
# a kilometre nothing in this project's physics is meant to apply either.
EXTENT_RANGE = (1e-6, 1e3)


@dataclass(frozen=True)
class Box:
    """The body: width (x), height (y) and length (z) in metres."""

    width: float = 0.01
    height: float = 0.01
    length: float = 0.03

    def __post_init__(self) -> None:
        for name in ("width", "height", "length"):
            v = getattr(self, name)
            low, high = EXTENT_RANGE
            if not (is_real(v) and low <= v <= high):
                raise SceneError(f"{name}={shown(v)} is out of range; allowed: number in [{low:g}, {high:g}] m")

    @property
    def extent(self) -> np.ndarray:
        return np.array([self.width, self.height, self.length])

    @property
    def volume(self) -> float:
        return self.width * self.height * self.length

    def holds(self, point: object) -> bool:
        """Whether `point` is three finite coordinates in the closed box (to 1e-9 of each dimension: a point
        computed on a face, W / 3 * 3, still counts)."""
        try:
            p = np.asarray(point, dtype=float)
        except (TypeError, ValueError):
            return False
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            return False
        tol = WHOLE * self.extent
        return bool(np.all(p >= -tol) and np.all(p <= self.extent + tol))

    def lattice_shape(self, n: int) -> tuple[int, int, int]:
        """Nodes per axis of the lattice of resolution n (one spacing a = width / (n - 1))."""
        if isinstance(n, bool) or int(n) != n or n < 2:
            raise SceneError(f"n={shown(n)} is out of range; allowed: integer >= 2")
        n = int(n)
        shape = [n]
        for name, ext in (("height", self.height), ("length", self.length)):
            cells = (n - 1) * ext / self.width
            whole = round(cells)
            if whole < 1 or abs(cells - whole) > WHOLE * max(1.0, cells):
                raise SceneError(f"n={n} does not fit the box: {name}/width = {ext / self.width:.6g}, so (n - 1) "
                                 f"{name}/width = {cells:.6g} spacings; allowed: n with a whole number of spacings "
                                 "along every axis")
            shape.append(whole + 1)
        return (shape[0], shape[1], shape[2])

    def lattice_spacing(self, n: int) -> float:
        """Spacing a of the lattice of resolution n."""
        self.lattice_shape(n)
        return self.width / (n - 1)

    def lattice_points(self, n: int) -> np.ndarray:
        """Lattice nodes of resolution n, shape (N, 3), ordered x slowest, z fastest.

        Node (i, j, k) has index (i * ny + j) * nz + k.
        """
        shape = self.lattice_shape(n)
        axes = [np.linspace(0.0, ext, cnt) for ext, cnt in zip(self.extent, shape, strict=True)]
        grid = np.meshgrid(*axes, indexing="ij")
        return np.stack([g.ravel() for g in grid], axis=1)


@dataclass(frozen=True)
class Resolution:
    """Lattice resolution n and, for grids, an integer refinement (h = a / refine)."""

    n: int
    refine: int = 1

    def __post_init__(self) -> None:
        for name, low in (("n", 2), ("refine", 1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not low <= v <= 1000:
                raise SceneError(f"{name}={v!r} is out of range; allowed: integer in [{low}, 1000]")

    def spacing(self, width: float) -> float:
        """Grid spacing h = a / refine with a = width / (n - 1)."""
        return width / (self.n - 1) / self.refine
