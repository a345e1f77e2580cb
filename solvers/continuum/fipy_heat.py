"""FiPy finite-volume heat solver (steady and transient conduction) on the bar.

The continuum reference for the heat scenes on FiPy's node-centred grid: constraints and loads reach FiPy's own
discretisation, the step matrices are factored once, and values are interpolated to the shared sample points.
The cell layout, the patch variants (cut, staircase, fraction), the loads, the theta-method and the interpolation:
(docs/physics.md, "Continuum references", FiPy).
"""

from __future__ import annotations

import gc
import time
from typing import Any

import fipy
import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.interpolate import RegularGridInterpolator

from pcverify.scene import (
    FaceTemperature,
    PatchTemperature,
    PointTemperature,
    Resolution,
    Scene,
    SceneError,
)
from pcverify.solvers.continuum.assembly import grid_graph, split_free
from pcverify.solvers.continuum.fipy_fast import diffusion_term, tensor_grid3d
from pcverify.solvers.continuum.grid import held_node
from pcverify.solvers.continuum.linear_solver import smoothed_aggregation
from pcverify.solvers.continuum.parameters import FIPY_HEAT
from pcverify.solvers.continuum.work import heat_estimate, transient_steps
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params, heat_summary

_FACE_AXIS = {"x0": (0, 0), "xW": (0, 1), "y0": (1, 0), "yH": (1, 1), "z0": (2, 0), "zL": (2, 1)}
_FIPY_FACES = {"x0": "facesLeft", "xW": "facesRight", "y0": "facesBottom", "yH": "facesTop",
               "z0": "facesFront", "zL": "facesBack"}
SUBSAMPLES = 8  # per axis and cell, for patch volume fractions
PHYSICS = frozenset({"conduction", "heat-source", "heat-source-field", "interface-flux"})  # implemented


def grid_axes(scene: Scene, resolution: Resolution) -> tuple[list[np.ndarray], list[float]]:
    """Cell edges per axis of the dual grid and the spacing h per axis."""
    edges, hs = [], []
    for ext, cnt in zip(scene.box.extent, scene.box.lattice_shape(resolution.n), strict=True):
        m = (cnt - 1) * resolution.refine + 1  # refined nodes = cells on this axis
        h = float(ext) / (m - 1)
        e = np.concatenate([[0.0], (np.arange(m - 1) + 0.5) * h, [float(ext)]])
        edges.append(e)
        hs.append(h)
    return edges, hs


def _centres(e: np.ndarray) -> np.ndarray:
    return 0.5 * (e[1:] + e[:-1])


def _cell_of(edges: list[np.ndarray], point) -> tuple[int, int, int]:
    """Index of the cell that contains `point` (boundary points go to the boundary cell)."""
    return tuple(int(np.clip(np.searchsorted(e, p, side="right") - 1, 0, len(e) - 2))
                 for e, p in zip(edges, point, strict=True))


def patch_fraction(edges: list[np.ndarray], centre, radius: float, sub: int = SUBSAMPLES):
    """Volume fraction of cells inside a sphere, by sub*sub*sub midpoint samples per cell.

    Returns (index ranges per axis, fractions array over that block) for the cells whose box
    can intersect the sphere.
    """
    ranges, coords = [], []
    for e, c in zip(edges, centre, strict=True):
        lo = max(int(np.searchsorted(e, c - radius, side="right")) - 1, 0)
        hi = min(int(np.searchsorted(e, c + radius, side="left")), len(e) - 1)
        ranges.append((lo, hi))
        w = np.diff(e[lo:hi + 1])
        s = e[lo:hi, None] + w[:, None] * (np.arange(sub) + 0.5)[None, :] / sub  # (cells, sub)
        coords.append((s - c) ** 2)
    dx2, dy2, dz2 = coords
    r2 = radius * radius
    frac = np.empty((dx2.shape[0], dy2.shape[0], dz2.shape[0]))
    yz = dy2[:, :, None, None] + dz2[None, None, :, :]  # (ny, sub, nz, sub)
    for i in range(dx2.shape[0]):  # slabs keep memory bounded; loops over cell columns only
        inside = (dx2[i][:, None, None, None, None] + yz[None]) <= r2
        frac[i] = inside.mean(axis=(0, 2, 4))
    return ranges, frac


def cell_load(scene: Scene, edges: list[np.ndarray]) -> np.ndarray:
    """Heat load per cell (W), shape (mx, my, mz): the volumetric source and the interface flux."""
    heat = scene.conduction
    widths = [np.diff(e) for e in edges]
    volumes = np.einsum("i,j,k->ijk", *widths)
    if heat.source_field:  # a varying source: its value at the cell centre times the volume (midpoint rule)
        centres = np.stack(np.meshgrid(*[_centres(e) for e in edges], indexing="ij"), axis=-1)
        load = heat.source_at(centres.reshape(-1, 3)).reshape(volumes.shape) * volumes
    else:
        load = heat.source * volumes
    plane = heat.interface
    if plane is None or plane.flux == 0.0:
        return load
    ax = plane.axis_index
    cen = _centres(edges[ax])
    hat = np.zeros(cen.size)
    j = int(np.searchsorted(cen, plane.position, side="right")) - 1
    if j < 0 or j >= cen.size - 1:  # between a face and the centre of its boundary cell
        hat[min(max(j, 0), cen.size - 1)] = 1.0
    else:
        t = (plane.position - cen[j]) / (cen[j + 1] - cen[j])
        hat[j], hat[j + 1] = 1.0 - t, t
    factors = [hat if d == ax else widths[d] for d in range(3)]
    return load + plane.flux * np.einsum("i,j,k->ijk", *factors)


def _pad_axis(vals: np.ndarray, centres: np.ndarray, edge: np.ndarray, axis: int,
              fixed: dict[int, float]) -> tuple[np.ndarray, np.ndarray]:
    """Pad `vals` with one face layer on each side of `axis` (the insulated-face quadratic: docs/physics.md, FiPy)."""
    v = np.moveaxis(vals, axis, 0)
    layers = []
    for side in (0, 1):
        if side in fixed:
            layers.append(np.full_like(v[0], fixed[side]))
            continue
        if side == 0:
            t0, t1, d0, d1 = v[0], v[1], centres[0] - edge[0], centres[1] - edge[0]
        else:
            t0, t1, d0, d1 = v[-1], v[-2], edge[-1] - centres[-1], edge[-1] - centres[-2]
        layers.append(t0 - (t1 - t0) * d0 * d0 / (d1 * d1 - d0 * d0))
    out = np.concatenate([layers[0][None], v, layers[1][None]], axis=0)
    ax = np.concatenate([[edge[0]], centres, [edge[-1]]])
    return np.moveaxis(out, 0, axis), ax


def interpolate(values: np.ndarray, edges: list[np.ndarray], fixed_faces: dict[str, float],
                points: np.ndarray) -> np.ndarray:
    """Trilinear interpolation of cell values (shape (mx, my, mz)) padded with face values."""
    ax_list = []
    v = values
    for axis in range(3):
        fixed = {side: val for face, val in fixed_faces.items()
                 for (a, side) in [_FACE_AXIS[face]] if a == axis}
        v, ax = _pad_axis(v, _centres(edges[axis]), edges[axis], axis, fixed)
        ax_list.append(ax)
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    for axis in range(3):  # points on the closed box; clip rounding just outside it
        pts[:, axis] = np.clip(pts[:, axis], ax_list[axis][0], ax_list[axis][-1])
    return RegularGridInterpolator(ax_list, v, method="linear")(pts)


class _Linear:
    """Solve A x = b for one fixed matrix: cached splu, or a reused pyamg hierarchy + CG."""

    def __init__(self, A: sp.csr_matrix, method: str, rtol: float, graph: sp.csr_matrix | None = None):
        self.method, self.rtol, self.A = method, rtol, A
        self.iterations = 0
        if A.shape[0] == 0:
            self.method = "empty"
        elif method == "direct":
            self.lu = spla.splu(A.tocsc())
        else:
            # Jacobi prolongation smoothing with the (seeded) spectral-radius estimate: 'local' Gershgorin
            # weighting needs no random numbers but took 20 CG iterations instead of 15 at 666 000 unknowns.
            # Aggregation on `graph` (cells sharing a node: 27 neighbours) on the finest level: the 7-point
            # FV stencil alone gave aggregates of ~8 cells, operator complexity 1.55 and a slow second level;
            # with the graph 3x3x3 aggregates, complexity 1.15, set-up + CG 2.7 s instead of 4.6 s (CPU, 673 501
            # cells, same 15 iterations).
            strength = {} if graph is None else {"strength": [("predefined", {"C": graph}),
                                                              ("symmetric", {"theta": 0.0})]}
            self.ml = smoothed_aggregation(A, symmetry="symmetric", max_coarse=500, **strength)

    def __call__(self, b: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        if self.method == "empty":
            return b.copy()
        if self.method == "direct":
            return self.lu.solve(b)
        bnorm = np.linalg.norm(b)
        if bnorm == 0.0:
            return np.zeros_like(b)
        res: list[float] = []
        x = self.ml.solve(b, x0=x0, tol=self.rtol, maxiter=500, accel="cg", residuals=res)
        self.iterations += max(len(res) - 1, 0)
        true_res = np.linalg.norm(b - self.A @ x) / bnorm
        if not true_res <= 10 * self.rtol:  # check the field we return, not the solver's flag
            raise RuntimeError(f"AMG-CG did not converge: true relative residual {true_res:.3g} > {10 * self.rtol:g}")
        return x


class FipyHeat:
    """FiPy cell-centred finite volumes on the node-centred dual grid of the refined lattice."""

    name = "fipy"
    kind = "continuum"
    parameters = FIPY_HEAT

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        """Cells (one per lattice-grid node), time steps and memory of the solve."""
        return heat_estimate(scene, resolution)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if "conduction" not in scene.physics or not scene.physics <= PHYSICS:
            return False, (f"fipy heat solver does conduction (with {', '.join(sorted(PHYSICS - {'conduction'}))}) "
                           f"only; scene needs {sorted(scene.physics)}")
        if scene.conduction.mode == "steady" and not scene.constraints:
            return False, "steady conduction without any prescribed temperature is singular"
        for c in scene.constraints:
            if not isinstance(c, (FaceTemperature, PointTemperature, PatchTemperature)):
                return False, f"constraint {type(c).__name__} is not supported"
        return True, ""

    # ------------------------------------------------------------------ assembly
    def _fixed_cells(self, scene, edges, shape, patch_mode):
        """Fixed mask, T_fix, partial fractions (fraction mode) and patch id (cut mode) per cell."""
        fixed = np.zeros(shape, dtype=bool)
        tfix = np.zeros(shape)
        frac = np.zeros(shape)  # partial fractions (fraction mode), 0 elsewhere
        pid = np.full(shape, -1)  # which patch fixed the cell (cut mode)
        point_cells = []
        fallback: list[int] = []  # patches that "cut" handled with "fraction" (no centre inside rho)
        cen = [_centres(e) for e in edges]
        for ic, c in enumerate(scene.constraints):
            if isinstance(c, PointTemperature):  # the cell of the node at the point (grid.held_node's rule)
                idx = held_node(c.point, float(scene.box.width) / (shape[0] - 1), shape)
                fixed[idx] = True
                tfix[idx] = c.value
                point_cells.append((idx, c.value))
            elif isinstance(c, PatchTemperature):
                inside = None
                if patch_mode in ("staircase", "cut"):
                    d2 = ((cen[0][:, None, None] - c.centre[0]) ** 2 + (cen[1][None, :, None] - c.centre[1]) ** 2
                          + (cen[2][None, None, :] - c.centre[2]) ** 2)
                    inside = d2 <= c.radius ** 2
                    if not inside.any():
                        if patch_mode == "staircase":  # the point limit: the cell holding the corner node
                            inside[_cell_of(edges, c.centre)] = True
                        else:
                            inside = None  # cut: too coarse for a fixed cell; this patch falls back to fraction
                        fallback.append(ic)
                if inside is not None:
                    fixed |= inside
                    tfix[inside] = c.value
                    pid[inside] = ic
                else:
                    ((i0, i1), (j0, j1), (k0, k1)), f = patch_fraction(edges, c.centre, c.radius)
                    sl = (slice(i0, i1), slice(j0, j1), slice(k0, k1))
                    if not (f > 0.0).any():  # smaller than a sub-sample: the point limit, the centre's cell
                        idx = _cell_of(edges, c.centre)
                        fixed[idx], tfix[idx] = True, c.value
                        point_cells.append((idx, c.value))
                        continue
                    full = f >= 1.0
                    part = (f > 0.0) & ~full
                    blk_fixed, blk_t, blk_f = fixed[sl], tfix[sl], frac[sl]
                    blk_fixed |= full
                    blk_t[full | part] = c.value
                    blk_f[part] = np.maximum(blk_f[part], f[part])
        frac[fixed] = 0.0
        return fixed, tfix, frac, pid, point_cells, fallback

    @staticmethod
    def _cut_coefficients(scene, mesh, fixed_f, pid_f, k):
        """Face diffusion coefficients k / theta on faces between a free and a patch-fixed cell.

        theta in (0, 1] is where the sphere cuts the segment from the free to the fixed cell centre
        (Shortley-Weller): the flux through the face is k (T_fix - T_c) / (theta d).
        """
        ids = np.ma.getdata(mesh.faceCellIDs)
        interior = ~np.ma.getmaskarray(mesh.faceCellIDs)[1]
        kf = np.full(mesh.numberOfFaces, float(k))
        a, b = ids[0], ids[1]
        cut = interior & (fixed_f[a] != fixed_f[b]) & ((pid_f[a] >= 0) | (pid_f[b] >= 0))
        if not cut.any():
            return kf, 0
        free_c = np.where(fixed_f[a[cut]], b[cut], a[cut])
        fix_c = np.where(fixed_f[a[cut]], a[cut], b[cut])
        xc = np.asarray(mesh.cellCenters, dtype=float).T
        p0, p1 = xc[free_c], xc[fix_c]
        centre = np.array([scene.constraints[i].centre for i in pid_f[fix_c]])
        radius = np.array([scene.constraints[i].radius for i in pid_f[fix_c]])
        d = p1 - p0
        qa = np.sum(d * d, axis=1)
        qb = np.sum(d * (p0 - centre), axis=1)
        qc = np.sum((p0 - centre) ** 2, axis=1) - radius ** 2
        theta = (-qb - np.sqrt(np.maximum(qb * qb - qa * qc, 0.0))) / qa
        kf[np.flatnonzero(cut)] = k / np.clip(theta, 1e-3, 1.0)
        return kf, int(cut.sum())

    def _fipy_system(self, scene, edges, patch_mode, fixed_f, pid_f, stock):
        """FiPy mesh + DiffusionTerm(k) with the face constraints -> K (SPD), f, cell volumes, cut faces, fixed faces.

        Returns plain arrays only: no FiPy object outlives this call (see `_assemble`).
        """
        fp = fipy
        dxyz = [np.diff(e) for e in edges]
        if stock:
            mesh, term = fp.Grid3D(dx=dxyz[0], dy=dxyz[1], dz=dxyz[2]), fp.DiffusionTerm
        else:
            mesh, term = tensor_grid3d(*dxyz), diffusion_term
        k = scene.material.conductivity
        T = fp.CellVariable(mesh=mesh, value=scene.conduction.initial_temperature)
        fixed_faces = {}
        for c in scene.constraints:
            if isinstance(c, FaceTemperature):
                T.constrain(c.value, where=getattr(mesh, _FIPY_FACES[c.face]))
                fixed_faces[c.face] = c.value
        ncut = 0
        coeff: Any = k
        if patch_mode == "cut" and (pid_f >= 0).any():
            kf, ncut = self._cut_coefficients(scene, mesh, fixed_f, pid_f, k)
            coeff = fp.FaceVariable(mesh=mesh, value=kf)
        solver = term(coeff=coeff)._prepareLinearSystem(T, None, (), None)
        K = -sp.csr_matrix(solver.matrix.matrix)
        f = -np.asarray(solver.RHSvector, dtype=float).copy()
        vol = np.array(mesh.cellVolumes, dtype=float)
        return K, f, vol, ncut, fixed_faces

    def _assemble(self, scene, edges, hs, p, stock: bool = False):
        """FiPy's K (SPD) and f for the scene (`_fipy_system`), plus the penalty diagonal of fixed cells.

        stock=True builds with plain `fipy.Grid3D` / `fipy.DiffusionTerm`: the reference for the subclasses of
        fipy_fast, which give the same K and f bit for bit, faster (tests/test_fipy_fast.py, benchmark).
        FiPy's mesh and variables reference each other, so their arrays (1.3 GB at 673 501 cells) are freed only by
        Python's cyclic collector, whenever it next runs: measured inside the next solve, which then took
        7.0-8.6 s instead of 4.8-5.9 s.  So the FiPy set-up runs with the collector paused (all its objects stay
        in the youngest generation) and one collection of that generation (~ms) frees them as it returns.
        """
        t0 = time.perf_counter()
        shape = tuple(len(e) - 1 for e in edges)
        k = scene.material.conductivity
        fixed, tfix, frac, pid, point_cells, fallback = self._fixed_cells(scene, edges, shape, p["patch"])
        to_flat = lambda a: np.asarray(a).transpose(2, 1, 0).ravel()  # noqa: E731  FiPy: x fastest
        fixed_f, tfix_f, frac_f, pid_f = to_flat(fixed), to_flat(tfix), to_flat(frac), to_flat(pid)
        enabled = gc.isenabled()
        gc.disable()
        try:
            K, f, vol, ncut, fixed_faces = self._fipy_system(scene, edges, p["patch"], fixed_f, pid_f, stock)
        finally:
            if enabled:
                gc.enable()
        gc.collect(0)
        # penalty source (FiPy's ImplicitSourceTerm: S_P V_P on the diagonal, S_P V_P T_fix on the right)
        B = np.zeros(K.shape[0])
        B[fixed_f] = p["penalty"] * k / min(hs) ** 2
        part = frac_f > 0
        B[part] = frac_f[part] / (1.0 - frac_f[part]) * K.diagonal()[part] / vol[part]
        K = (K + sp.diags(B * vol)).tocsr()
        load = to_flat(cell_load(scene, edges))
        f = f + B * vol * tfix_f + load
        return dict(K=K, f=f, vol=vol, shape=shape, fixed=fixed_f, tfix=tfix_f, B=B, ncut=ncut,
                    fixed_faces=fixed_faces, point_cells=point_cells, fallback=fallback, heat_input=float(load.sum()),
                    assembly_s=time.perf_counter() - t0)

    # ------------------------------------------------------------------ solve
    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        t_wall = time.perf_counter()
        p = effective_params(self, params)
        if p["rannacher_steps"] % 2:
            raise SceneError(f"rannacher_steps={p['rannacher_steps']!r} is out of range; allowed: even integer "
                             "in [0, 100] (half steps that replace whole Crank-Nicolson steps)")
        ok, why = self.supports(scene)
        if not ok:
            raise SceneError(why)
        heat = scene.conduction
        nsteps = transient_steps(heat, p["max_steps"])
        if nsteps:
            if p["scheme"] == "crank-nicolson" and p["rannacher_steps"] > 2 * nsteps:
                raise SceneError(f"rannacher_steps={p['rannacher_steps']!r} is out of range; allowed: even integer "
                                 f"in [0, {2 * nsteps}] (2 x number of steps)")
        edges, hs = grid_axes(scene, resolution)
        sysd = self._assemble(scene, edges, hs, p)
        K, f, fixed, tfix = sysd["K"], sysd["f"], sysd["fixed"], sysd["tfix"]
        free = ~fixed
        nfree = int(free.sum())
        method = p["linear_solver"]
        if method == "auto":
            method = "direct" if nfree <= p["amg_threshold"] else "amg"
        t_solve = time.perf_counter()
        # cell adjacency graph for AMG aggregation; FiPy numbers cells x fastest, grid_graph z fastest
        Kff, Kfc = split_free(K, free)  # no copies when no cell is fixed (face constraints act through faces)
        graph = split_free(grid_graph(sysd["shape"][::-1]), free)[0] if method == "amg" else None
        T = np.full(K.shape[0], float(scene.conduction.initial_temperature))
        T[fixed] = tfix[fixed]
        tc = tfix[fixed]
        solvers: list[_Linear] = []
        steps_taken = 0
        if scene.conduction.mode == "steady":
            lin = _Linear(Kff, method, p["rtol"], graph)
            solvers.append(lin)
            T[free] = lin(f[free] - Kfc @ tc)
        else:
            C = scene.material.density * scene.material.heat_capacity * sysd["vol"]
            plan: list[tuple[float, float, int]] = []  # (dt, theta, count)
            if p["scheme"] == "implicit-euler":
                plan.append((scene.conduction.dt, 1.0, nsteps))
            else:
                r = p["rannacher_steps"]
                if r:
                    plan.append((scene.conduction.dt / 2, 1.0, r))
                if nsteps - r // 2:
                    plan.append((scene.conduction.dt, 0.5, nsteps - r // 2))
            for dt, theta, count in plan:
                A = (sp.diags(C[free] / dt) + theta * Kff).tocsr()
                lin = _Linear(A, method, p["rtol"], graph)
                solvers.append(lin)
                for _ in range(count):
                    rhs = C * T / dt - (1.0 - theta) * (K @ T) + f
                    T[free] = lin(rhs[free] - theta * (Kfc @ tc), x0=T[free])
                    steps_taken += 1
        solve_s = time.perf_counter() - t_solve

        # ---- output
        t_max = scene.conduction.t_max
        Tg = T.reshape(sysd["shape"][::-1]).transpose(2, 1, 0)  # (mx, my, mz)
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {}
        for name, pts in sets.items():
            pts = np.asarray(pts, dtype=float).reshape(-1, 3)
            vals = interpolate(Tg, edges, sysd["fixed_faces"], pts)
            for c in scene.constraints:
                if isinstance(c, PatchTemperature):
                    vals[np.sum((pts - np.asarray(c.centre)) ** 2, axis=1) <= c.radius ** 2] = c.value
            for idx, value in sysd["point_cells"]:
                inside = np.ones(len(pts), dtype=bool)
                for a in range(3):
                    inside &= (pts[:, a] >= edges[a][idx[a]]) & (pts[:, a] <= edges[a][idx[a] + 1])
                vals[inside] = value
            out[name] = {"points": pts, "values": vals / t_max}
        volume_mean = float(np.sum(T * sysd["vol"]) / scene.box.volume / t_max)
        nodes_vals = out["nodes"]["values"] if "nodes" in out else np.array([np.nan])
        iterations = sum(s.iterations for s in solvers)
        return Solution(
            scene=scene.name, solver=self.name, params=p,
            resolution={"n": resolution.n, "refine": resolution.refine, "h": hs[0], "nodes": int(K.shape[0])},
            samples=out, unknowns=int(nfree), wall_s=time.perf_counter() - t_wall, status="ok",
            work={"unknowns": int(nfree), "time_steps": steps_taken, "iterations": iterations,
                  "assembly_s": sysd["assembly_s"], "solve_s": solve_s},
            summary=heat_summary(nodes_vals, volume_mean),
            diagnostics={"linear_method": method, "free_unknowns": nfree, "fixed_cells": int(fixed.sum()),
                         "partial_cells": int(np.count_nonzero((sysd["B"] > 0) & free)), "cut_faces": sysd["ncut"],
                         "patch_fallback_to_fraction": len(sysd["fallback"]) if p["patch"] == "cut" else 0,
                         "patch_at_centre_cell": len(sysd["fallback"]) if p["patch"] == "staircase" else 0,
                         "cells_per_axis": list(sysd["shape"]), "heat_input_W": sysd["heat_input"],
                         "fixed_max_dev": float(np.max(np.abs(T[fixed] - tfix[fixed])) / t_max) if fixed.any()
                         else 0.0},
        )
