"""Automata of the movable cellular automaton (MCA) method on a rectangular simple-cubic lattice
(docs/physics.md, "The movable cellular automaton (MCA) model": packing).

"nodes" (`build_automata`, `bar_automata`): Voronoi cells of the lattice nodes clipped by the body, for which
sum_j q S = 3 Omega and sum_j q S n (x) n = Omega I hold exactly (why the uniaxial tests return E and nu);
"cells" (`cell_automata`): equal cubes, with wall bonds and condensed free faces ("The MCA solver in detail").
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from pcverify.scene import Box, Contact, SceneError

WHOLE = 1e-9  # relative tolerance of "on a node plane" / "midway between node planes"


@dataclass(frozen=True, eq=False)
class Automata:
    """Rest positions (N, 3), cell extents (N, 3), volumes, masses, inertia; pairs (P, 2), r0, S."""

    shape: tuple[int, int, int]
    spacing: np.ndarray  # (3,) lattice spacing per axis
    positions: np.ndarray
    extent: np.ndarray
    volume: np.ndarray
    mass: np.ndarray
    inertia: np.ndarray
    pairs: np.ndarray
    r0: np.ndarray
    area: np.ndarray
    axis: np.ndarray  # lattice axis (0, 1, 2) of each pair
    body: np.ndarray | None = None  # (N,) body of each automaton (contact scenes: 0 below the interface, 1 above)
    packing: str = "nodes"  # "nodes" (centres on the faces) or "cells" (equal cubes, centres a/2 inside)
    free_faces: np.ndarray | None = None  # (N,) "cells": faces of each automaton on a free face of the body

    def many_body_volume(self, lam: float, kn: float) -> np.ndarray:
        """The volume the many-body term divides by: Omega_i, times 1 + m_i lam / (2 kn) for an automaton
        with m_i free faces ("cells"; docs/physics.md, "The MCA solver in detail")."""
        if self.free_faces is None or lam == 0.0:
            return self.volume
        return self.volume * (1.0 + 0.5 * self.free_faces * lam / kn)

    def with_free_faces(self, held: list[str], box_extent: np.ndarray) -> Automata:
        """These automata with `free_faces` counted: the body's faces not in `held` ("cells" only)."""
        if self.packing != "cells":
            return self
        count = np.zeros(self.size)
        for face in ("x0", "xW", "y0", "yH", "z0", "zL"):
            if face not in held:
                count[self.on_face(face, box_extent)] += 1
        return replace(self, free_faces=count)

    @property
    def size(self) -> int:
        return int(self.positions.shape[0])

    def node_at(self, points: np.ndarray) -> np.ndarray:
        """Indices of the automata centred at `points` (k, 3); SceneError if a point is not a centre."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        dist, idx = cKDTree(self.positions).query(pts)
        bad = np.flatnonzero(dist > 1e-6 * float(self.spacing.min()))
        if bad.size:
            raise SceneError(f"sample point {pts[bad[0]].tolist()} is not an automaton centre; the mca solver "
                             "reports at its automata only")
        return idx.astype(np.int64)

    def holds(self, points: np.ndarray) -> np.ndarray:
        """Mask of the `points` (k, 3) that are automaton centres."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        dist, _ = cKDTree(self.positions).query(pts)
        return dist <= 1e-6 * float(self.spacing.min())

    def on_face(self, face: str, box_extent: np.ndarray) -> np.ndarray:
        """Indices of the automata whose cell lies on `face` (x0, xW, y0, yH, z0, zL): the centres on the face
        ("nodes"), the layer of centres a/2 inside it ("cells")."""
        ax = "xyz".index(face[0])
        target = 0.0 if face[1] == "0" else float(box_extent[ax])
        if self.packing == "cells":
            target += 0.5 * float(self.spacing[ax]) * (1.0 if face[1] == "0" else -1.0)
        return np.flatnonzero(np.abs(self.positions[:, ax] - target) <= 1e-9 * float(box_extent[ax]))

    def face_strain(self, u: np.ndarray, ax: int, box_extent: np.ndarray) -> float:
        """Mean normal strain along axis `ax`: the difference of the volume-weighted mean displacements `u` of the
        automata on its two faces, over the distance between their centres."""

        def mean(face: str) -> float:
            idx = self.on_face(face, box_extent)
            return float((u[idx, ax] * self.volume[idx]).sum() / self.volume[idx].sum())

        span = box_extent[ax] if self.packing == "nodes" else box_extent[ax] - self.spacing[ax]
        return (mean(f"{'xyz'[ax]}{'WHL'[ax]}") - mean(f"{'xyz'[ax]}0")) / span

    def sampler(self, points: np.ndarray) -> sp.csr_matrix:
        """Matrix (k, N) that takes a field at the automata to its values at `points` (k, 3).  "nodes": the
        automaton centred at each point (SceneError if a point is not a centre).  "cells": trilinear
        interpolation between the centres, linear extrapolation over the last a/2 to a face (both second
        order in a for a smooth field; exact for a linear one)."""
        pts = np.atleast_2d(np.asarray(points, dtype=float))
        k = pts.shape[0]
        if self.packing != "cells":
            idx = self.node_at(pts)
            return sp.csr_matrix((np.ones(k), (np.arange(k), idx)), shape=(k, self.size))
        shape = np.asarray(self.shape)
        s = pts / self.spacing - 0.5  # position in units of a from the first centre, per axis
        base = np.clip(np.floor(s), 0, np.maximum(shape - 2, 0)).astype(np.int64)
        t = np.where(shape > 1, s - base, 0.0)
        rows, cols, vals = [], [], []
        for corner in np.ndindex(2, 2, 2):
            c = np.asarray(corner)
            w = np.prod(np.where(c == 1, t, 1.0 - t), axis=1)
            node = np.minimum(base + c, shape - 1)
            rows.append(np.arange(k))
            cols.append(np.ravel_multi_index(tuple(node.T), tuple(shape)))
            vals.append(w)
        return sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                             shape=(k, self.size)).tocsr()

    def walls(self, faces: list[str], frictionless: list[bool], box_extent: np.ndarray
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Wall bonds of the "cells" packing on `faces`: (automaton index, outward unit normal (k, 3), face
        area, frictionless) of the face layer, face by face in the order given; empty for "nodes", whose face
        automata sit on the face itself."""
        idx, normal, area = [np.zeros(0, dtype=np.int64)], [np.zeros((0, 3))], [np.zeros(0)]
        slide = [np.zeros(0, dtype=bool)]
        if self.packing == "cells":
            for face, smooth in zip(faces, frictionless, strict=True):
                ax = "xyz".index(face[0])
                on = self.on_face(face, box_extent)
                nv = np.zeros((on.size, 3))
                nv[:, ax] = -1.0 if face[1] == "0" else 1.0
                other = [o for o in range(3) if o != ax]
                idx.append(on)
                normal.append(nv)
                area.append(self.extent[on][:, other].prod(axis=1))
                slide.append(np.full(on.size, smooth))
        return np.concatenate(idx), np.concatenate(normal), np.concatenate(area), np.concatenate(slide)


def build_automata(extent: np.ndarray, shape: tuple[int, int, int], density: float) -> Automata:
    """Automata of a rectangular body `extent` (3,) with `shape` nodes per axis (each >= 2)."""
    ext = np.asarray(extent, dtype=float)
    if len(shape) != 3 or min(shape) < 2:
        raise SceneError(f"shape={shape!r} is out of range; allowed: three integers >= 2")
    if not (np.all(np.isfinite(ext)) and np.all(ext > 0)):
        raise SceneError(f"extent={ext.tolist()!r} is out of range; allowed: three numbers in (0, inf) m")
    if not (math_finite(density) and density > 0):
        raise SceneError(f"density={density!r} is out of range; allowed: number in (0, inf) kg/m^3")
    h = ext / (np.asarray(shape) - 1)
    axes = [np.linspace(0.0, e, c) for e, c in zip(ext, shape, strict=True)]
    cell = []
    for hh, c in zip(h, shape, strict=True):
        w = np.full(c, hh)
        w[0] = w[-1] = hh / 2
        cell.append(w)
    grid = np.meshgrid(*axes, indexing="ij")
    pos = np.stack([g.ravel() for g in grid], axis=1)
    cg = np.meshgrid(*cell, indexing="ij")
    extent_i = np.stack([g.ravel() for g in cg], axis=1)
    vol = extent_i.prod(axis=1)
    mass = density * vol
    inertia = mass * (extent_i**2).sum(axis=1) / 18.0
    pr, ax_arr = face_pairs(tuple(shape))
    r0 = h[ax_arr]
    other = np.array([(1, 2), (0, 2), (0, 1)])[ax_arr]
    ei = extent_i[pr[:, 0]]
    area = np.take_along_axis(ei, other, axis=1).prod(axis=1)
    return Automata(shape=tuple(int(s) for s in shape), spacing=h, positions=pos, extent=extent_i, volume=vol,
                    mass=mass, inertia=inertia, pairs=pr, r0=r0, area=area, axis=ax_arr)


def face_pairs(shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray]:
    """The pairs (i, j) of face neighbours of automata indexed x slowest, z fastest on a grid of `shape`, and
    the axis each pair lies along (the x pairs first, then y, then z)."""
    idx = np.arange(int(np.prod(shape))).reshape(shape)
    pairs, axis = [], []
    for ax in range(3):
        lo = [slice(None)] * 3
        hi = [slice(None)] * 3
        lo[ax] = slice(0, -1)
        hi[ax] = slice(1, None)
        pairs.append(np.stack([idx[tuple(lo)].ravel(), idx[tuple(hi)].ravel()], axis=1))
        axis.append(np.full(pairs[-1].shape[0], ax))
    return np.concatenate(pairs).astype(np.int64), np.concatenate(axis).astype(np.int64)


def cell_automata(box: Box, n: int, density: float) -> Automata:
    """Automata of the "cells" packing of resolution n: n equal cubes across the width (a = W / n), a whole
    number of them along y and z, centres a/2 inside the faces; pairs link face neighbours (r0 = a, S = a^2)."""
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise SceneError(f"n={n!r} is out of range; allowed: integer >= 1 (automata across the width)")
    if not (math_finite(density) and density > 0):
        raise SceneError(f"density={density!r} is out of range; allowed: number in (0, inf) kg/m^3")
    ext = np.asarray(box.extent, dtype=float)
    a = float(ext[0]) / int(n)
    shape = [int(n)]
    for name, e in (("height", ext[1]), ("length", ext[2])):
        cells = e / a
        if round(cells) < 1 or abs(cells - round(cells)) > WHOLE * max(1.0, cells):
            raise SceneError(f"n={n} does not fit the box with packing=cells: {name} / a = {cells:.6g} automata; "
                             "allowed: n with a whole number of automata (a = width / n) along every axis")
        shape.append(int(round(cells)))
    axes = [(np.arange(c) + 0.5) * a for c in shape]
    grid = np.meshgrid(*axes, indexing="ij")
    pos = np.stack([g.ravel() for g in grid], axis=1)
    count = pos.shape[0]
    extent_i = np.full((count, 3), a)
    vol = np.full(count, a**3)
    mass = np.full(count, density * a**3)
    inertia = mass * a * a / 6.0  # m (3 a^2) / 18
    pr, ax_arr = face_pairs(tuple(shape))
    return Automata(shape=(shape[0], shape[1], shape[2]), spacing=np.full(3, a), positions=pos, extent=extent_i,
                    volume=vol, mass=mass, inertia=inertia, pairs=pr, r0=np.full(len(pr), a),
                    area=np.full(len(pr), a * a), axis=ax_arr, packing="cells")


def bar_automata(box: Box, n: int, density: float) -> Automata:
    """Automata of the lattice of resolution n of the box (one spacing d = a = W/(n - 1) on every axis)."""
    if int(n) != n or n < 2:
        raise SceneError(f"n={n!r} is out of range; allowed: integer >= 2")
    return build_automata(box.extent, box.lattice_shape(int(n)), density)


def body_automata(box: Box, n: int, density: float, contact: Contact) -> tuple[Automata, Automata]:
    """The automata of the two bodies of a contact scene, and the same automata bonded across the interface
    (the reference geometry, and the stiffness that bounds the stable step).  Body 1 holds the lattice's nodes
    below the interface, body 2 those above it (within `span`, if given); each automaton is its node's Voronoi
    cell clipped by its body, so the cells meet on the interface midway between two node planes (h0 = d)."""
    whole = bar_automata(box, n, density)
    a = float(whole.spacing[contact.axis_index])
    cells = contact.position / a - 0.5
    inside = 0 <= round(cells) < whole.shape[contact.axis_index] - 1
    if abs(cells - round(cells)) > WHOLE * max(1.0, cells) or not inside:
        raise SceneError(f"contact position={contact.position!r} is not midway between two node planes at n={n} "
                         f"(spacing {a:.6g} m); allowed: n with position / spacing - 1/2 a whole number")
    pos = whole.positions
    upper = pos[:, contact.axis_index] > contact.position
    keep = np.ones(whole.size, dtype=bool)
    lo = np.zeros(3)
    hi = np.asarray(box.extent, dtype=float).copy()
    lo2, hi2 = lo.copy(), hi.copy()
    lo2[contact.axis_index] = hi[contact.axis_index] = contact.position  # body 1 below, body 2 above the plane
    if contact.span is not None:
        d = contact.direction_index
        for end in contact.span:
            k = end / float(whole.spacing[d])
            if abs(k - round(k)) > WHOLE * max(1.0, k):
                raise SceneError(f"contact span end {end!r} is not on a node plane at n={n}; allowed: a whole number "
                                 "of spacings")
        along = pos[:, d]
        tol = WHOLE * float(box.extent[d])
        keep = ~upper | ((along >= contact.span[0] - tol) & (along <= contact.span[1] + tol))
        lo2[d], hi2[d] = contact.span
    idx = np.flatnonzero(keep)
    body = upper[idx].astype(np.int64)
    p = pos[idx]
    h = whole.spacing
    low = np.where(body[:, None] == 1, lo2, lo)
    high = np.where(body[:, None] == 1, hi2, hi)
    extent = np.minimum(p + h / 2, high) - np.maximum(p - h / 2, low)
    vol = extent.prod(axis=1)
    mass = density * vol
    inertia = mass * (extent**2).sum(axis=1) / 18.0
    new_index = np.full(whole.size, -1)
    new_index[idx] = np.arange(idx.size)
    pairs = new_index[whole.pairs]
    both = np.all(pairs >= 0, axis=1)
    pairs, axis = pairs[both], whole.axis[both]
    same = body[pairs[:, 0]] == body[pairs[:, 1]]
    other = np.array([(1, 2), (0, 2), (0, 1)])[axis]
    area = np.take_along_axis(extent[pairs[:, 0]], other, axis=1).prod(axis=1)
    r0 = h[axis]

    def make(sel: np.ndarray) -> Automata:
        return Automata(shape=whole.shape, spacing=h, positions=p, extent=extent, volume=vol, mass=mass,
                        inertia=inertia, pairs=pairs[sel], r0=r0[sel], area=area[sel], axis=axis[sel], body=body)

    return make(same), make(np.ones(len(pairs), dtype=bool))


def math_finite(x: float) -> bool:
    return bool(np.isfinite(x))
