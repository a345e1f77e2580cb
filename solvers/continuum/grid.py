"""Structured hexahedral grids on the bar, conforming corner-patch warps, point location (for the continuum
solvers).

The grid of resolution (n, refine) has the particle lattice of resolution n among its nodes; node (i, j, k) is
(i * ny + j) * nz + k (the order of `Box.lattice_points`), cells in MeshHex1 order; the warp and the location
(docs/physics.md, "Continuum references", "The structured grid").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from pcverify.scene import SceneError

NODE_TOL = 1e-9  # a point within this fraction of h of a grid node is that node


def node_ijk(x: np.ndarray, h: float, shape: tuple[int, int, int], tol: float = NODE_TOL) -> np.ndarray:
    """(k, 3) indices of the nodes at the points x (k, 3) of a grid of spacing h with `shape` nodes from the
    origin; ValueError naming the first point that is not a node (to tol h)."""
    x = np.atleast_2d(np.asarray(x, dtype=float))
    ijk = np.rint(x / h).astype(np.int64)
    off = np.abs(ijk * h - x).max(axis=1)
    bad = (off > tol * h) | np.any(ijk < 0, axis=1) | np.any(ijk >= np.asarray(shape), axis=1)
    if np.any(bad):
        raise ValueError(f"point {tuple(float(v) for v in x[np.argmax(bad)])} is not a node of the grid with "
                         f"spacing h={h:g} m")
    return ijk


def held_node(point, h: float, shape: tuple[int, int, int]) -> tuple[int, int, int]:
    """The node a PointTemperature holds on a grid of spacing h = a / refine: the node at its point, the same
    rule in every continuum solver (scikit-fem's node, FiPy's node-centred cell) and in the particle solvers
    (the particle at the point, refine 1).  A point between nodes is refused, never moved to a nearby node:
    SceneError naming the point and h."""
    try:
        i, j, k = (int(v) for v in node_ijk(np.asarray([point]), h, shape)[0])
    except ValueError as exc:
        raise SceneError(f"point constraint: {exc}; allowed: points on grid nodes (h = a / refine: the "
                         "lattice nodes of n, and more of them at refine > 1)") from None
    return i, j, k


# Corner offsets (di, dj, dk) of a cell, in scikit-fem MeshHex1 local order (as in MeshHex1.init_tensor).
HEX_CORNERS = np.array(
    [[0, 0, 0], [0, 1, 0], [1, 0, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1], [1, 1, 1]], dtype=np.int64
)

# Balances the cube-to-sphere distortion: shell nodes on the axes move out by ~KAPPA, those on the
# cube diagonal move in by ~sqrt(3)/KAPPA (KAPPA = 3**0.25 makes both factors equal).
KAPPA = 3.0**0.25


def _smooth_fall(xi: np.ndarray) -> np.ndarray:
    """phi(xi) = (1 - xi)^2 (1 + 2 xi): 1 at 0, 0 at 1, zero slope at both ends."""
    return (1.0 - xi) ** 2 * (1.0 + 2.0 * xi)


def _smooth_fall_slope(xi: np.ndarray) -> np.ndarray:
    return -6.0 * xi * (1.0 - xi)


@dataclass(frozen=True)
class SphereWarp:
    """Radial warp that puts the max-norm shell s = s1 of a grid onto the sphere |x - c| = rho.

    C1 across s = s2 (`_smooth_fall`), a bijection while R increases along every ray (`min_slope`); the map and
    why the warps of a refinement sequence differ by O(h): docs/physics.md, "The structured grid".
    """

    centre: tuple[float, float, float]
    rho: float
    s1: float
    s2: float

    def _geometry(self, x: np.ndarray):
        u = np.asarray(x, dtype=float) - np.asarray(self.centre)
        t = np.linalg.norm(u, axis=1)
        s = np.abs(u).max(axis=1)
        return u, t, s

    def radius(self, t: np.ndarray, s: np.ndarray) -> np.ndarray:
        """New distance R from the centre of points at distance t and max-norm distance s."""
        t = np.asarray(t, dtype=float)
        s = np.asarray(s, dtype=float)
        r = t.copy()
        pos = s > 0
        inner = pos & (s <= self.s1)
        r[inner] = self.rho * s[inner] / self.s1
        band = (s > self.s1) & (s < self.s2)
        t1 = self.s1 * t[band] / s[band]
        xi = (s[band] - self.s1) / (self.s2 - self.s1)
        r[band] = t[band] + (self.rho - t1) * _smooth_fall(xi)
        return r

    def apply(self, x: np.ndarray) -> np.ndarray:
        """Warped positions of points x, shape (k, 3)."""
        u, t, s = self._geometry(x)
        out = np.array(x, dtype=float, copy=True)
        move = (s > 0) & (s < self.s2)
        if np.any(move):
            r = self.radius(t[move], s[move])
            out[move] = np.asarray(self.centre) + u[move] * (r / t[move])[:, None]
        return out

    def inverse(self, y: np.ndarray) -> np.ndarray:
        """Pre-images of warped points y (bisection on the monotone radial map, to ~1e-15 relative)."""
        u, r, s = self._geometry(y)
        out = np.array(y, dtype=float, copy=True)
        move = (s > 0) & (s < self.s2)
        if not np.any(move):
            return out
        um, rm, sm = u[move], r[move], s[move]
        ratio = sm / rm  # max-norm / euclidean: a function of the direction only
        lo = np.zeros_like(rm)
        hi = self.s2 / ratio  # t2 along this ray; R(t2) = t2 >= r
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            big = self.radius(mid, mid * ratio) > rm
            hi = np.where(big, mid, hi)
            lo = np.where(big, lo, mid)
        t = 0.5 * (lo + hi)
        out[move] = np.asarray(self.centre) + um * (t / rm)[:, None]
        return out

    def min_slope(self, samples: int = 65) -> float:
        """Smallest dR/dt over directions and the band s1 < s < s2 (relative to 1 = no stretch)."""
        # worst case over directions: ratio s/t in [1/sqrt(3), 1]; dR/dt is affine in (rho - t1)
        xi = np.linspace(0.0, 1.0, samples)
        worst = np.inf
        for ratio in (1.0 / math.sqrt(3.0), 1.0):
            t1 = self.s1 / ratio
            t2 = self.s2 / ratio
            slope = 1.0 + (self.rho - t1) * _smooth_fall_slope(xi) / (t2 - t1)
            worst = min(worst, float(slope.min()), self.rho / t1)
        return worst


def plan_sphere_warp(centre, rho: float, h: float, limit: float) -> SphereWarp:
    """Choose s1 = m h (m = max(1, round(rho / (KAPPA h)))) and s2 <= `limit` (`StructuredGrid.patch_limit`) for
    a patch of radius rho: 5 rho if that fits, never less than what keeps dR/dt >= 0.25 (else ValueError).  A
    wide band matters: with s2 = 3 rho the values 3.3 rho from a patch converged at order ~1.4, with 5 rho ~2.6."""
    m = max(1, int(round(rho / (KAPPA * h))))
    s1 = m * h
    if s1 >= limit:
        raise ValueError(f"patch radius {rho:g} m: shell s1={s1:g} m does not fit below the limit {limit:g} m")
    # dR/dt >= 1 - 1.5 (rho - s1) / (s2 - s1) on the axis rays (the worst ones when rho > s1)
    need = s1 + 2.0 * max(rho - s1, 0.0)
    s2 = min(max(5.0 * rho, need, s1 + h), limit)
    if s2 < need:
        raise ValueError(f"patch radius {rho:g} m: no room for a valid warp (needs s2 >= {need:g} m, "
                         f"limit {limit:g} m)")
    return SphereWarp(tuple(float(c) for c in centre), float(rho), float(s1), float(s2))


def hex_connectivity(shape: tuple[int, int, int]) -> np.ndarray:
    """Cell-to-node table (8, ncells) in MeshHex1 local order for a grid of `shape` nodes; cells are numbered
    like nodes, cell (i, j, k) -> (i * (ny - 1) + j) * (nz - 1) + k."""
    nx, ny, nz = shape
    i, j, k = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), np.arange(nz - 1), indexing="ij")
    i, j, k = i.ravel(), j.ravel(), k.ravel()
    t = np.empty((8, i.size), dtype=np.int64)
    for c, (di, dj, dk) in enumerate(HEX_CORNERS):
        t[c] = ((i + di) * ny + (j + dj)) * nz + (k + dk)
    return t


def corner_jacobians(p: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Jacobian determinants (9, ncells) of the trilinear cells t (8, ncells) of nodes p at their 8 corners and
    their centre: h^3 on an undistorted cube of side h."""
    offs = {tuple(o): c for c, o in enumerate(HEX_CORNERS)}
    x = p[t]  # (8, ncells, 3)
    out = np.empty((9, t.shape[1]))
    for c, (a, b, d) in enumerate(HEX_CORNERS):
        sa, sb, sd = 1 - 2 * a, 1 - 2 * b, 1 - 2 * d  # direction into the cell
        ex = (x[offs[(1 - a, b, d)]] - x[c]) * sa
        ey = (x[offs[(a, 1 - b, d)]] - x[c]) * sb
        ez = (x[offs[(a, b, 1 - d)]] - x[c]) * sd
        out[c] = np.einsum("ij,ij->i", np.cross(ex, ey), ez)
    # centre: derivatives of the trilinear map at (1/2, 1/2, 1/2)
    grads = _trilinear_grads(np.full((t.shape[1], 3), 0.5))  # (ncells, 8, 3)
    jac = np.einsum("cnk,cnl->nkl", x, np.moveaxis(grads, 1, 0))
    out[8] = np.linalg.det(jac)
    return out


def _trilinear_weights(xi: np.ndarray) -> np.ndarray:
    """Shape functions (k, 8) at local coordinates xi (k, 3) in [0, 1]^3, HEX_CORNERS order."""
    o = HEX_CORNERS[None, :, :]
    f = np.where(o == 1, xi[:, None, :], 1.0 - xi[:, None, :])
    return f.prod(axis=2)


def _trilinear_grads(xi: np.ndarray) -> np.ndarray:
    """Gradients (k, 8, 3) of the shape functions with respect to the local coordinates."""
    o = HEX_CORNERS[None, :, :]
    f = np.where(o == 1, xi[:, None, :], 1.0 - xi[:, None, :])
    df = np.where(o == 1, 1.0, -1.0) * np.ones_like(f)
    g = np.empty(f.shape)
    g[..., 0] = df[..., 0] * f[..., 1] * f[..., 2]
    g[..., 1] = f[..., 0] * df[..., 1] * f[..., 2]
    g[..., 2] = f[..., 0] * f[..., 1] * df[..., 2]
    return g


@dataclass
class StructuredGrid:
    """Structured hexahedral grid (possibly warped near patches) of a box with uniform spacing h."""

    extent: np.ndarray
    shape: tuple[int, int, int]
    h: float
    points: np.ndarray  # (N, 3), warped
    warps: list[SphereWarp] = field(default_factory=list)
    cells: np.ndarray | None = None  # (8, ncells) MeshHex1 order

    @classmethod
    def for_box(cls, extent, h_cells: tuple[int, int, int]) -> StructuredGrid:
        """Unwarped grid with `h_cells` cells per axis (their spacings must agree)."""
        extent = np.asarray(extent, dtype=float)
        hs = extent / np.asarray(h_cells, dtype=float)
        if not np.allclose(hs, hs[0], rtol=1e-10):
            raise ValueError(f"box {tuple(extent)} is not a uniform grid of {h_cells} cells")
        shape = tuple(int(c) + 1 for c in h_cells)
        axes = [np.linspace(0.0, e, c) for e, c in zip(extent, shape, strict=True)]
        g = np.meshgrid(*axes, indexing="ij")
        pts = np.stack([a.ravel() for a in g], axis=1)
        return cls(extent, shape, float(hs[0]), pts, [], hex_connectivity(shape))

    @classmethod
    def lattice(cls, extent, n: int, refine: int) -> StructuredGrid:
        """The refined particle-lattice grid of a box: (n-1)*refine cells across x and as many cells of the
        same width along y and z as the box holds (the bar: (3n-3)*refine along z)."""
        c = (n - 1) * refine
        extent = np.asarray(extent, dtype=float)
        cy = int(round(extent[1] / extent[0] * c))
        cz = int(round(extent[2] / extent[0] * c))
        return cls.for_box(extent, (c, cy, cz))

    @property
    def reference_points(self) -> np.ndarray:
        g = np.meshgrid(*[np.arange(s) * self.h for s in self.shape], indexing="ij")
        return np.stack([a.ravel() for a in g], axis=1)

    def node_index(self, ijk: np.ndarray) -> np.ndarray:
        ijk = np.asarray(ijk, dtype=np.int64)
        _, ny, nz = self.shape
        return (ijk[..., 0] * ny + ijk[..., 1]) * nz + ijk[..., 2]

    def nearest_node(self, x: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Index of the unwarped grid node at each point x (k, 3); ValueError if a point is not a node."""
        return self.node_index(node_ijk(x, self.h, self.shape, tol))

    def face_nodes(self, face: str) -> np.ndarray:
        """Nodes on a box face x0, xW, y0, yH, z0 or zL (faces stay planar under the warps)."""
        axis = "xyz".index(face[0])
        at_low = face[1] == "0"
        ijk = np.unravel_index(np.arange(int(np.prod(self.shape))), self.shape)
        return np.flatnonzero(ijk[axis] == (0 if at_low else self.shape[axis] - 1))

    def patch_limit(self, centre, others) -> float:
        """Largest s2 for a warp about `centre`: half the max-norm distance to other patch centres, and
        the distance to any box face not through `centre`."""
        c = np.asarray(centre, dtype=float)
        lim = np.inf
        for o in others:
            d = float(np.abs(np.asarray(o, dtype=float) - c).max())
            if d > 0:
                lim = min(lim, 0.5 * d)
        for ax in range(3):
            lo, hi = c[ax], self.extent[ax] - c[ax]
            for dist in (lo, hi):
                if dist > 1e-12 * self.extent[ax]:
                    lim = min(lim, dist)
        return lim

    def add_warp(self, warp: SphereWarp) -> np.ndarray:
        """Apply a sphere warp to the nodes (its cube must not overlap another's: `patch_limit`); returns the
        indices of the nodes inside the patch (s <= s1)."""
        for w in self.warps:
            gap = np.abs(np.asarray(w.centre) - np.asarray(warp.centre)).max()
            if gap < w.s2 + warp.s2 - 1e-12 * self.h:
                raise ValueError("overlapping patch warps")
        c = np.asarray(warp.centre)
        ref = self.reference_points
        s = np.abs(ref - c).max(axis=1)
        zone = np.flatnonzero(s < warp.s2)
        self.points[zone] = warp.apply(ref[zone])
        self.warps.append(warp)
        return np.flatnonzero(s <= warp.s1 * (1 + 1e-12))

    def warped_cells(self) -> np.ndarray:
        """Indices of cells with at least one node moved by a warp."""
        moved = np.abs(self.points - self.reference_points).max(axis=1) > 1e-14 * self.h
        return np.flatnonzero(moved[self.cells].any(axis=0))

    def min_scaled_jacobian(self) -> float:
        """min over warped cells of det J / h^3 at corners and centre (1 on an undistorted cell)."""
        cells = self.warped_cells()
        if cells.size == 0:
            return 1.0
        return float(corner_jacobians(self.points, self.cells[:, cells]).min() / self.h**3)

    # ---- point location and interpolation -------------------------------------------------------

    def _cell_of_reference(self, xr: np.ndarray) -> np.ndarray:
        ijk = np.floor(xr / self.h).astype(np.int64)
        return np.clip(ijk, 0, np.asarray(self.shape) - 2)

    def locate(self, x: np.ndarray, tol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
        """Cell (i, j, k) lower indices (k, 3) and local coordinates (k, 3) in [0, 1]^3 of points x (Newton to
        ~1e-13 in warped cells); ValueError for points outside the box or not found."""
        x = np.atleast_2d(np.asarray(x, dtype=float))
        span = self.extent
        if np.any(x < -tol * self.h) or np.any(x > span + tol * self.h):
            raise ValueError("sample point outside the box")
        xr = x.copy()
        warped = np.zeros(len(x), dtype=bool)
        for w in self.warps:
            s = np.abs(x - np.asarray(w.centre)).max(axis=1)
            zone = s < w.s2
            if np.any(zone):
                xr[zone] = w.inverse(x[zone])
                warped |= zone
        ijk = self._cell_of_reference(xr)
        xi = np.clip((xr - ijk * self.h) / self.h, 0.0, 1.0)
        if np.any(warped):
            idx = np.flatnonzero(warped)
            cij, cxi = self._newton_search(x[idx], ijk[idx], xi[idx], tol)
            ijk[idx], xi[idx] = cij, cxi
        return ijk, xi

    def _newton(self, x, ijk, xi0, iters=30):
        corner_nodes = self.node_index(ijk[:, None, :] + HEX_CORNERS[None, :, :])  # (k, 8)
        cx = self.points[corner_nodes]  # (k, 8, 3)
        xi = xi0.copy()
        for _ in range(iters):
            f = np.einsum("kc,kcd->kd", _trilinear_weights(xi), cx) - x
            jac = np.einsum("kcd,kce->kde", cx, _trilinear_grads(xi))
            try:
                step = np.linalg.solve(jac, f[..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.einsum("kde,ke->kd", np.linalg.pinv(jac), f)
            xi = xi - step
            xi = np.clip(xi, -0.5, 1.5)
            if np.abs(step).max() < 1e-14:
                break
        res = np.abs(np.einsum("kc,kcd->kd", _trilinear_weights(xi), cx) - x).max(axis=1)
        return xi, res

    def _newton_search(self, x, ijk, xi0, tol):
        xi, res = self._newton(x, ijk, xi0)
        inside = np.all((xi > -tol) & (xi < 1 + tol), axis=1) & (res < 1e-9 * self.h)
        if not np.all(inside):
            offsets = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)
                                if (a, b, c) != (0, 0, 0)])
            for off in offsets:
                todo = np.flatnonzero(~inside)
                if todo.size == 0:
                    break
                cand = ijk[todo] + off
                ok = np.all((cand >= 0) & (cand <= np.asarray(self.shape) - 2), axis=1)
                todo, cand = todo[ok], cand[ok]
                if todo.size == 0:
                    continue
                cxi, cres = self._newton(x[todo], cand, np.full((todo.size, 3), 0.5))
                good = np.all((cxi > -tol) & (cxi < 1 + tol), axis=1) & (cres < 1e-9 * self.h)
                ijk[todo[good]] = cand[good]
                xi[todo[good]] = cxi[good]
                inside[todo[good]] = True
        if not np.all(inside):
            bad = x[np.flatnonzero(~inside)[0]]
            raise ValueError(f"could not locate point {tuple(bad)} in the warped grid")
        return ijk, np.clip(xi, 0.0, 1.0)

    def interpolation_matrix(self, x: np.ndarray) -> sp.csr_matrix:
        """Sparse (k, N) matrix P with P @ nodal_values = Q1 field at the points x."""
        ijk, xi = self.locate(x)
        # snap round-off so that a point on a node takes exactly that node's value
        xi = np.where(np.abs(xi) < 1e-12, 0.0, np.where(np.abs(xi - 1.0) < 1e-12, 1.0, xi))
        nodes = self.node_index(ijk[:, None, :] + HEX_CORNERS[None, :, :])  # (k, 8)
        w = _trilinear_weights(xi)
        rows = np.repeat(np.arange(len(xi)), 8)
        return sp.csr_matrix((w.ravel(), (rows, nodes.ravel())), shape=(len(xi), len(self.points)))
