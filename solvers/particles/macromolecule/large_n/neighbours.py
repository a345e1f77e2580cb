"""Neighbour lists for large lattices: a cell list builds a Verlet list with a skin, rebuilt on demand.

A list has two parts:

- offset groups (a lattice stencil): index offsets o > 0 such that the pairs (i, i + o) of every
  slot i = 0 .. N - o - 1 are evaluated, whatever their distance (a force pass zeroes those beyond
  r_cut).  For a lattice in lattice order the 16 half-shell offsets hold every interacting pair, so
  a force pass runs over contiguous data (vectorisable) and the list costs no memory per particle.
  The offsets are chosen once (`stencil_offsets`, from the rest lattice) and never change;
- a residual CSR list: row i holds every j != i with |x_j - x_i| < radius = r_cut + skin at build
  time and |j - i| not a group offset, in ascending j (canonical: two lists holding the same pairs
  are equal array for array).  Empty for a vibrating lattice in lattice order; everything for a
  list built without groups (e.g. particles in random order).  "Full" (each pair in both rows) so
  that a force pass can gather: particle i writes only its own slot, no write races, a fixed order.

Indices are int32 (4 bytes per residual entry), row offsets int64.

Rebuild on demand: while no particle has moved more than skin/2 since the build, no pair that
was beyond the radius can have come within r_cut (two particles close in by at most skin), so
groups plus residual still hold every interacting pair.  `NeighbourList.update` rebuilds when that
bound is passed and counts the builds.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from pcverify.scene import SceneError


@njit(cache=True, error_model="numpy")
def _cells(x, radius):
    """Cell of every particle (cells at least `radius` wide) and the particles sorted by cell."""
    n = x.shape[0]
    lo = np.empty(3)
    dims = np.empty(3, dtype=np.int64)
    width = np.empty(3)
    for d in range(3):
        mn = x[0, d]
        mx = x[0, d]
        for i in range(n):
            mn = min(mn, x[i, d])
            mx = max(mx, x[i, d])
        lo[d] = mn
        dims[d] = max(1, int((mx - mn) / radius))
        width[d] = max((mx - mn) / dims[d], radius)
    ncell = dims[0] * dims[1] * dims[2]
    cell = np.empty(n, dtype=np.int64)
    for i in range(n):
        c = 0
        for d in range(3):
            k = min(int((x[i, d] - lo[d]) / width[d]), dims[d] - 1)
            c = c * dims[d] + k
        cell[i] = c
    cstart = np.zeros(ncell + 1, dtype=np.int64)
    for i in range(n):
        cstart[cell[i] + 1] += 1
    for c in range(ncell):
        cstart[c + 1] += cstart[c]
    fill = cstart[:-1].copy()
    members = np.empty(n, dtype=np.int32)
    for i in range(n):  # stable counting sort: members of a cell in ascending index
        members[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return cell, cstart, members, dims


@njit(cache=True, inline="always", error_model="numpy")
def dist2(p, ip, q, iq):
    """Squared distance between row ip of p and row iq of q, rows named by index tuples ((i,) or (i, k)):
    the one expression of every distance test.  Index tuples, not row views: a view costs a reference
    count per call in the hot loops."""
    return ((p[ip + (0,)] - q[iq + (0,)]) ** 2 + (p[ip + (1,)] - q[iq + (1,)]) ** 2
            + (p[ip + (2,)] - q[iq + (2,)]) ** 2)


@njit(cache=True, inline="always", error_model="numpy")
def _scan(x, i, cell, cstart, members, dims, r2max, index, p0, fill):
    """Neighbours j != i of particle i closer than sqrt(r2max), searched in the 27 cells around i's:
    returns their number and, if fill, inserts them in ascending j into index[p0:] (row kept sorted).
    One body for the counting and the filling pass of `_build`."""
    ny = dims[1]
    nz = dims[2]
    c = cell[i]
    cx = c // (ny * nz)
    cy = (c // nz) % ny
    cz = c % nz
    m = 0
    for ax in range(max(cx - 1, 0), min(cx + 2, dims[0])):
        for ay in range(max(cy - 1, 0), min(cy + 2, ny)):
            for az in range(max(cz - 1, 0), min(cz + 2, nz)):
                cc = (ax * ny + ay) * nz + az
                for q in range(cstart[cc], cstart[cc + 1]):
                    j = members[q]
                    if j == i:
                        continue
                    if dist2(x, (j,), x, (i,)) < r2max:
                        if fill:  # insertion into the sorted row
                            s = p0 + m
                            while s > p0 and index[s - 1] > j:
                                index[s] = index[s - 1]
                                s -= 1
                            index[s] = j
                        m += 1
    return m


@njit(cache=True, parallel=True, error_model="numpy")
def _build(x, radius):
    """CSR Verlet list (start int64 (N+1), index int32) of all j != i closer than radius, rows ascending."""
    n = x.shape[0]
    cell, cstart, members, dims = _cells(x, radius)
    r2max = radius * radius
    counts = np.zeros(n, dtype=np.int64)
    none = np.empty(0, dtype=np.int32)
    for i in prange(n):
        counts[i] = _scan(x, i, cell, cstart, members, dims, r2max, none, 0, False)
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        start[i + 1] = start[i] + counts[i]
    index = np.empty(start[n], dtype=np.int32)
    for i in prange(n):
        _scan(x, i, cell, cstart, members, dims, r2max, index, start[i], True)
    return start, index


@njit(cache=True, error_model="numpy")  # serial: once per build
def _drop_offsets(start, index, offsets):
    """The CSR list without the entries whose |j - i| is one of `offsets` (rows stay ascending)."""
    n = start.shape[0] - 1
    keep = np.ones(index.shape[0], dtype=np.bool_)
    out_start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        m = 0
        for p in range(start[i], start[i + 1]):
            o = abs(np.int64(index[p]) - i)
            for g in range(offsets.shape[0]):
                if o == offsets[g]:
                    keep[p] = False
            m += keep[p]
        out_start[i + 1] = out_start[i] + m
    return out_start, index[keep]


@njit(cache=True, error_model="numpy")  # serial: called once per rebuild check outside the kernels
def moved_beyond(x, x_ref, limit):
    """Number of particles displaced more than `limit` from x_ref (non-finite positions count too)."""
    n = x.shape[0]
    lim2 = limit * limit
    over = 0
    for i in range(n):
        if not dist2(x, (i,), x_ref, (i,)) <= lim2:
            over += 1
    return over


@dataclass(eq=False)
class NeighbourList:
    """Offset groups plus a full residual Verlet list in CSR form: row i = index[start[i]:start[i+1]]
    (ascending j, offsets |j - i| of the groups left out)."""

    start: np.ndarray
    index: np.ndarray
    x_ref: np.ndarray
    r_cut: float
    skin: float
    offsets: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    builds: int = 1
    history: list[int] = field(default_factory=list)  # step of each rebuild after the first

    @property
    def radius(self) -> float:
        return self.r_cut + self.skin

    @property
    def size(self) -> int:
        return int(self.start.shape[0] - 1)

    @property
    def entries(self) -> int:
        """Entries of the residual list (each residual pair twice)."""
        return int(self.index.shape[0])

    @property
    def reach(self) -> int:
        """Largest group offset (0 without groups)."""
        return int(self.offsets.max()) if self.offsets.size else 0

    @property
    def nbytes(self) -> int:
        """Memory held by the list (groups, residual offsets and indices, the reference positions)."""
        return int(self.offsets.nbytes + self.start.nbytes + self.index.nbytes + self.x_ref.nbytes)

    def expired(self, x: np.ndarray) -> bool:
        """True once some particle has moved more than skin/2 since the build."""
        return bool(moved_beyond(x, self.x_ref, 0.5 * self.skin) > 0)

    def rebuild(self, x: np.ndarray, step: int = -1) -> None:
        """Build again from positions x."""
        self.start, self.index = _residual(np.ascontiguousarray(x, dtype=np.float64), self.radius, self.offsets)
        self.x_ref = np.array(x, dtype=np.float64, copy=True)
        self.builds += 1
        self.history.append(step)

    def update(self, x: np.ndarray, step: int = -1) -> bool:
        """Rebuild if expired; returns whether it did."""
        if self.expired(x):
            self.rebuild(x, step)
            return True
        return False

    def pairs(self) -> np.ndarray:
        """(P, 2) unique pairs i < j within the radius at build (residual entries and group slots; rows
        ascending).  For checks and tests; not used by kernels."""
        i = np.repeat(np.arange(self.size, dtype=np.int64), np.diff(self.start))
        j = self.index.astype(np.int64)
        keep = i < j
        parts = [np.stack([i[keep], j[keep]], axis=1)]
        for o in self.offsets:
            lo = np.arange(self.size - o, dtype=np.int64)
            near = np.einsum("ij,ij->i", self.x_ref[lo + o] - self.x_ref[lo], self.x_ref[lo + o] - self.x_ref[lo])
            lo = lo[near < self.radius**2]
            parts.append(np.stack([lo, lo + o], axis=1))
        out = np.concatenate(parts)
        return out[np.lexsort((out[:, 1], out[:, 0]))]


@njit(cache=True, error_model="numpy")
def _build_serial(x, radius):
    """`_build` on one thread (small N: the parallel launches cost more than the scan)."""
    n = x.shape[0]
    cell, cstart, members, dims = _cells(x, radius)
    r2max = radius * radius
    none = np.empty(0, dtype=np.int32)
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        start[i + 1] = start[i] + _scan(x, i, cell, cstart, members, dims, r2max, none, 0, False)
    index = np.empty(start[n], dtype=np.int32)
    for i in range(n):
        _scan(x, i, cell, cstart, members, dims, r2max, index, start[i], True)
    return start, index


@njit(cache=True, error_model="numpy")  # serial driver; large sets are built in parallel
def _union(xk, radius, offsets):
    """Residual CSR list holding every pair within `radius` in any of the K position sets xk (K, N, 3)
    (offsets `offsets` left out): one call for an ensemble's K builds and their union (rows ascending)."""
    nk = xk.shape[0]
    n = xk.shape[1]
    keys = np.empty(0, dtype=np.int64)
    for k in range(nk):
        start, index = _build(xk[k], radius) if n > 4096 else _build_serial(xk[k], radius)
        if offsets.shape[0] > 0:
            start, index = _drop_offsets(start, index, offsets)
        ki = np.empty(index.shape[0], dtype=np.int64)
        for i in range(n):
            for p in range(start[i], start[i + 1]):
                ki[p] = i * n + index[p]
        keys = np.concatenate((keys, ki))
    keys = np.unique(keys)
    out_start = np.zeros(n + 1, dtype=np.int64)
    out_index = np.empty(keys.shape[0], dtype=np.int32)
    for p in range(keys.shape[0]):
        out_start[keys[p] // n + 1] += 1
        out_index[p] = keys[p] % n
    for i in range(n):
        out_start[i + 1] += out_start[i]
    return out_start, out_index


def union_list(xk: np.ndarray, r_cut: float, skin: float, offsets: np.ndarray) -> NeighbourList:
    """One list for K position sets xk (K, N, 3) of the same particles: groups `offsets` and the union of
    the K residual lists (what `merge_lists` of K `build_neighbours` gives, in one numba call); x_ref
    is the first set.  Used by ensembles at every rebuild."""
    xk = np.ascontiguousarray(xk, dtype=np.float64)
    start, index = _union(xk, float(r_cut + skin), np.ascontiguousarray(offsets, dtype=np.int64))
    return NeighbourList(start=start, index=index, x_ref=xk[0].copy(), r_cut=float(r_cut), skin=float(skin),
                         offsets=np.ascontiguousarray(offsets, dtype=np.int64))


def _residual(x: np.ndarray, radius: float, offsets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    start, index = _build(x, radius)
    return _drop_offsets(start, index, offsets) if offsets.size else (start, index)


def stencil_offsets(x: np.ndarray, radius: float, min_fill: float = 0.25, min_pairs: int = 16) -> np.ndarray:
    """Offsets o > 0 (ascending int64) whose slots (i, i + o) are pairs within `radius` for at least
    min_fill of the N - o slots and at least min_pairs times: the groups of a list over particles in
    lattice order (none in random order, where a large o with a few slots could pass the fill test
    by chance).  Called on the rest lattice, so the groups never depend on the motion."""
    start, index = _build(np.ascontiguousarray(x, dtype=np.float64), float(radius))
    n = start.shape[0] - 1
    off = index.astype(np.int64) - np.repeat(np.arange(n, dtype=np.int64), np.diff(start))
    cand, count = np.unique(off[off > 0], return_counts=True)
    return cand[(count >= min_fill * (n - cand)) & (count >= min_pairs)].astype(np.int64)


def build_neighbours(x: np.ndarray, r_cut: float, skin: float, offsets: np.ndarray | None = None) -> NeighbourList:
    """Verlet list of positions x (N, 3) for interaction range r_cut and skin (same length unit), with
    the offset groups `offsets` (default none: every pair in the residual CSR list)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 1:
        raise SceneError(f"positions of shape {x.shape} are not allowed; allowed: (N, 3) with N >= 1")
    if x.shape[0] >= 2**31:
        raise SceneError(f"N={x.shape[0]} particles is out of range; allowed: N < 2**31 (int32 indices)")
    if not (math.isfinite(r_cut) and r_cut > 0.0):
        raise SceneError(f"r_cut={r_cut!r} is out of range; allowed: number in (0, inf)")
    if not (math.isfinite(skin) and skin > 0.0):
        raise SceneError(f"skin={skin!r} is out of range; allowed: number in (0, inf)")
    if not np.isfinite(x).all():
        raise SceneError("positions contain NaN or Inf; allowed: finite numbers")
    offsets = np.zeros(0, dtype=np.int64) if offsets is None else np.ascontiguousarray(offsets, dtype=np.int64)
    if offsets.size and not (offsets.min() > 0 and offsets.max() < x.shape[0] and np.all(np.diff(offsets) > 0)):
        raise SceneError(f"offsets={offsets.tolist()!r} are not allowed; allowed: ascending integers in [1, N)")
    start, index = _residual(x, r_cut + skin, offsets)
    return NeighbourList(start=start, index=index, x_ref=x.copy(), r_cut=float(r_cut), skin=float(skin),
                         offsets=offsets)


def merge_lists(lists: list[NeighbourList]) -> NeighbourList:
    """Union of lists over the same particles and groups (rows ascending); x_ref and radius of the first.

    Used by ensembles: replicas share one list that holds every pair any replica needs.
    """
    first = lists[0]
    if any(not np.array_equal(nl.offsets, first.offsets) for nl in lists):
        raise ValueError("lists with different offset groups cannot be merged")
    n = first.size
    keys = np.unique(np.concatenate([
        np.repeat(np.arange(n, dtype=np.int64), np.diff(nl.start)) * n + nl.index.astype(np.int64) for nl in lists
    ]))
    start = np.zeros(n + 1, dtype=np.int64)
    np.cumsum(np.bincount(keys // n, minlength=n), out=start[1:])
    return NeighbourList(start=start, index=(keys % n).astype(np.int32), x_ref=first.x_ref.copy(),
                         r_cut=first.r_cut, skin=first.skin, offsets=first.offsets, builds=first.builds)
