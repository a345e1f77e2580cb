"""scikit-fem heat conduction solver: Q1 hexahedra on the refined particle lattice, steady and transient.

The finite-element reference for the heat scenes: nodal constraints eliminated by condensation, a conforming
patch by warping the grid, implicit Euler or Crank-Nicolson with a Rannacher start, SuperLU or AMG-CG.
The mesh, operator, constraints, loads, time stepping, linear algebra and output in full:
(docs/physics.md, "Continuum references", scikit-fem).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
import scipy.sparse as sp
from skfem import Basis, ElementHex1, LinearForm, MeshHex

from pcverify.scene import (
    Conduction,
    FaceTemperature,
    PatchTemperature,
    PointTemperature,
    Resolution,
    Scene,
    SceneError,
)
from pcverify.solvers.continuum.assembly import assemble_q1, grid_graph, plane_load, split_free
from pcverify.solvers.continuum.grid import StructuredGrid, held_node, plan_sphere_warp
from pcverify.solvers.continuum.linear_solver import SpdSolver, smoothed_aggregation
from pcverify.solvers.continuum.parameters import SKFEM_HEAT
from pcverify.solvers.continuum.work import heat_estimate, transient_steps
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params, heat_summary

PHYSICS = frozenset({"conduction", "heat-source", "heat-source-field", "interface-flux"})  # implemented

PARAMETERS = SKFEM_HEAT


def amg_options(graph: sp.spmatrix | None = None) -> dict[str, Any]:
    """pyamg smoothed-aggregation settings (measured at 666 000 free nodes, bar-heat-faces n=4 refine 20).

    - strength: aggregate on `graph` (the grid's node adjacency) on the finest level when given.  The fast
      assembly leaves out the Laplacian's exact zeros (edge neighbours), and aggregating on the remaining
      21-point pattern made ragged aggregates: 20 CG iterations instead of 14, operator complexity 1.14
      instead of 1.05.
    - smooth: Jacobi prolongation smoothing with 'local' (Gershgorin) weighting instead of the default
      spectral-radius estimate, which starts from an unseeded random vector (results then differ from run
      to run at the CG tolerance: not bit-reproducible) and costs ~1 s at this size.
    - improve_candidates=None: the constant is already the Laplacian's near-null space (set-up 1.1 s
      instead of 1.4 s, same iterations).
    """
    opts: dict[str, Any] = {"symmetry": "symmetric", "smooth": ("jacobi", {"weighting": "local"}),
                            "improve_candidates": None}
    if graph is not None:
        opts["strength"] = [("predefined", {"C": graph.tocsr()}), ("symmetric", {"theta": 0.0})]
    return opts


def _linear_solver(a: sp.spmatrix, method: str, rtol: float, graph: sp.spmatrix | None = None) -> SpdSolver:
    """SuperLU or CG with the SA-AMG hierarchy of `amg_options(graph)` for one constant SPD matrix.

    A failed CG raises ArithmeticError (as in skfem_elastic), which a study records as a failed cell.
    """

    def amg(mat: sp.csr_matrix) -> Any:
        return smoothed_aggregation(mat, **amg_options(graph))

    return SpdSolver(a, method, rtol, amg, error=ArithmeticError)


def _field_load(heat: Conduction, grid: StructuredGrid) -> np.ndarray:
    """Nodal load f_i = integral of s(x) phi_i of a varying source (uniform part included): scikit-fem's linear
    form with the source evaluated at the (possibly warped) cells' 2x2x2 Gauss points."""
    basis = Basis(MeshHex(np.ascontiguousarray(grid.points.T), grid.cells.astype(np.int32)), ElementHex1(),
                  intorder=2)

    @LinearForm
    def form(v, w):
        x = np.stack([np.asarray(c) for c in w.x], axis=-1)
        return heat.source_at(x.reshape(-1, 3)).reshape(x.shape[:-1]) * v

    return form.assemble(basis)


class SkfemHeat:
    """Heat conduction with scikit-fem Q1 hexahedra (steady and theta-method transient)."""

    name = "skfem"
    kind = "continuum"
    parameters = PARAMETERS

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        """Grid nodes, time steps and memory of the solve."""
        return heat_estimate(scene, resolution)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if "conduction" not in scene.physics or not scene.physics <= PHYSICS:
            return False, (f"skfem heat solver does conduction (with {', '.join(sorted(PHYSICS - {'conduction'}))}) "
                           f"only; scene needs {sorted(scene.physics)}")
        if scene.conduction.mode == "steady" and not scene.constraints:
            return False, "steady conduction without any prescribed temperature is singular"
        return True, ""

    # -- set-up ------------------------------------------------------------------------------------

    def _check(self, scene: Scene, p: dict[str, Any]) -> int:
        ok, why = self.supports(scene)
        if not ok:
            raise SceneError(why)
        if p["rannacher_steps"] % 2:
            raise SceneError(f"rannacher_steps={p['rannacher_steps']!r} is out of range; allowed: even integer "
                             "in [0, 1000] (half steps in pairs)")
        steps = transient_steps(scene.conduction, p["max_steps"])
        if steps == 0:
            return 0
        if p["scheme"] == "crank-nicolson" and p["rannacher_steps"] // 2 > steps:
            raise SceneError(f"rannacher_steps={p['rannacher_steps']!r} is out of range; allowed: even integer "
                             f"in [0, {2 * steps}] (2 * number of time steps)")
        return steps

    def _constrain(self, scene: Scene, grid: StructuredGrid, patch_mode: str) -> tuple[np.ndarray, dict]:
        """Fixed values per node (NaN = free); warps the grid for conforming patches."""
        fixed = np.full(len(grid.points), np.nan)
        diag: dict[str, Any] = {"patches": []}
        patches = [c for c in scene.constraints if isinstance(c, PatchTemperature)]
        centres = [c.centre for c in patches]
        if patch_mode == "conforming":
            for c in patches:  # warp first: point and face nodes are found by index, unaffected
                try:
                    grid.nearest_node(np.asarray([c.centre]))
                    warp = plan_sphere_warp(c.centre, c.radius, grid.h, grid.patch_limit(c.centre, centres))
                except ValueError as exc:
                    raise SceneError(f"patch='conforming' cannot represent the patch at {c.centre}: {exc}; "
                                     "allowed: patch centres on grid nodes with room for the warp "
                                     "(or patch='staircase')") from None
                inside = grid.add_warp(warp)
                diag["patches"].append({"centre": c.centre, "rho": c.radius, "s1": warp.s1, "s2": warp.s2,
                                        "fixed_nodes": int(inside.size), "min_slope": warp.min_slope()})
        for c in scene.constraints:
            if isinstance(c, FaceTemperature):
                nodes = grid.face_nodes(c.face)
            elif isinstance(c, PointTemperature):
                nodes = grid.node_index(np.asarray(held_node(c.point, grid.h, grid.shape)))
            elif isinstance(c, PatchTemperature):
                if patch_mode == "conforming":
                    d = np.linalg.norm(grid.points - np.asarray(c.centre), axis=1)
                    nodes = np.flatnonzero(d <= c.radius * (1 + 1e-9))
                else:
                    d = np.linalg.norm(grid.reference_points - np.asarray(c.centre), axis=1)
                    nodes = np.flatnonzero(d <= c.radius * (1 + 1e-12))
                    diag["patches"].append({"centre": c.centre, "rho": c.radius, "fixed_nodes": int(nodes.size)})
                if nodes.size == 0:
                    raise SceneError(f"patch at {c.centre} with rho={c.radius:g} m holds no grid node")
            else:  # pragma: no cover - the scene model has no other constraint kinds
                raise SceneError(f"constraint {type(c).__name__} is not supported by skfem")
            fixed[nodes] = c.value
        if grid.warps:
            jmin = grid.min_scaled_jacobian()
            diag["min_scaled_jacobian"] = jmin
            if not jmin > 0:
                raise SceneError(f"patch='conforming': warped grid has a non-positive Jacobian ({jmin:.3g}); "
                                 "allowed: a finer grid or patch='staircase'")
        return fixed, diag

    # -- solve --------------------------------------------------------------------------------------

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        wall0 = time.perf_counter()
        p = effective_params(self, params)
        steps = self._check(scene, p)
        n, refine = int(resolution.n), int(resolution.refine)
        box = scene.box
        grid = StructuredGrid.lattice(box.extent, n, refine)
        fixed, diag = self._constrain(scene, grid, p["patch"])
        is_fixed = ~np.isnan(fixed)
        free = np.flatnonzero(~is_fixed)
        bnd = np.flatnonzero(is_fixed)
        n_nodes = len(grid.points)

        method = p["linear_solver"]
        if method == "auto":
            method = "direct" if free.size <= p["direct_max_unknowns"] else "amg"
        t0 = time.perf_counter()
        ops = assemble_q1(grid, with_mass=scene.conduction.mode == "transient", full_pattern=method == "direct")
        mat = scene.material
        stiff = mat.conductivity * ops.stiffness
        weights = ops.weights
        load = self._load(scene, grid, weights)
        mss = mat.density * mat.heat_capacity * ops.mass if scene.conduction.mode == "transient" else None
        assembly_s = time.perf_counter() - t0

        t1 = time.perf_counter()
        temp = np.full(n_nodes, float(scene.conduction.initial_temperature))
        temp[bnd] = fixed[bnd]
        iterations = 0
        residual = 0.0
        n_solves = 0
        if scene.conduction.mode == "steady":
            k_ff, k_fb = split_free(stiff, ~is_fixed)
            graph = split_free(grid_graph(grid.shape), ~is_fixed)[0] if method == "amg" else None
            solver = _linear_solver(k_ff, method, p["cg_rtol"], graph)
            rhs = load[free] - k_fb @ fixed[bnd]
            del k_ff, k_fb, graph
            temp[free] = solver.solve(rhs)
            iterations, residual, n_solves = solver.iterations, solver.worst_residual, 1
        else:
            plan = self._time_plan(scene, p, steps)
            solvers: dict[tuple[float, float], tuple[SpdSolver, sp.csr_matrix, np.ndarray]] = {}
            for theta, dt in plan:
                key = (theta, dt)
                if key not in solvers:
                    a = (mss + theta * dt * stiff).tocsr()
                    b = (mss - (1.0 - theta) * dt * stiff).tocsr()
                    a_ff, a_fb = split_free(a, ~is_fixed)
                    solvers[key] = (_linear_solver(a_ff, method, p["cg_rtol"]), b[free], a_fb @ fixed[bnd])
                ls, b_free, lift = solvers[key]
                rhs = b_free @ temp - lift + dt * load[free]
                temp[free] = ls.solve(rhs, x0=temp[free])
                n_solves += 1
            iterations = sum(s[0].iterations for s in solvers.values())
            residual = max(s[0].worst_residual for s in solvers.values())
            cn = p["scheme"] == "crank-nicolson"
            diag["rannacher_half_steps"] = sum(1 for th, _ in plan if th == 1.0) if cn else 0
        solve_s = time.perf_counter() - t1

        if samples is None:
            samples = scene.sample_sets(n)
        out: dict[str, dict[str, np.ndarray]] = {}
        for key, pts in samples.items():
            pts = np.asarray(pts, dtype=float).reshape(-1, 3)
            try:
                interp = grid.interpolation_matrix(pts)
            except ValueError as exc:
                raise SceneError(f"samples[{key!r}]: {exc}") from None
            out[key] = {"points": pts, "values": interp @ temp / scene.conduction.t_max}
        node_pts = scene.sample_sets(n)["nodes"]
        if "nodes" in out:
            node_vals = out["nodes"]["values"]
        else:
            node_vals = grid.interpolation_matrix(node_pts) @ temp / scene.conduction.t_max
        volume = float(weights.sum())
        volume_mean = float(weights @ temp) / volume / scene.conduction.t_max
        summary = heat_summary(node_vals, volume_mean)
        diag["heat_input_W"] = float(load.sum())
        diag.update({"fixed_nodes": int(bnd.size), "free_nodes": int(free.size), "linear_solver": method,
                     "max_relative_residual": residual, "warped_cells": ops.warped_cells, "mesh_volume": volume,
                     "volume_error": volume / box.volume - 1.0})
        wall = time.perf_counter() - wall0
        return Solution(
            scene=scene.name, solver=self.name, params=p,
            resolution={"n": n, "refine": refine, "h": grid.h, "nodes": n_nodes},
            samples=out, unknowns=int(free.size), wall_s=wall, status="ok",
            work={"unknowns": int(free.size), "time_steps": n_solves if scene.conduction.mode == "transient" else 0,
                  "iterations": int(iterations), "assembly_s": assembly_s, "solve_s": solve_s},
            summary=summary, diagnostics=diag,
        )

    @staticmethod
    def _load(scene: Scene, grid: StructuredGrid, weights: np.ndarray) -> np.ndarray:
        """Nodal heat load (W): the volumetric source and the interface flux (docs/physics.md, scikit-fem)."""
        heat = scene.conduction
        load = heat.source * weights if not heat.source_field else _field_load(heat, grid)
        plane = heat.interface
        if plane is not None and plane.flux != 0.0:
            ax = plane.axis_index
            for w in grid.warps:
                if abs(plane.position - w.centre[ax]) < w.s2:
                    raise SceneError(f"interface position={plane.position!r} crosses the warped band of the patch at "
                                     f"{w.centre}; allowed: a plane farther than {w.s2:g} m from a patch centre "
                                     "along its axis (or patch='staircase')")
            load = load + plane.flux * plane_load(grid, ax, plane.position)
        return load

    @staticmethod
    def _time_plan(scene: Scene, p: dict[str, Any], steps: int) -> list[tuple[float, float]]:
        """(theta, dt) of every step: implicit Euler, or Rannacher half steps then Crank-Nicolson."""
        dt = scene.conduction.t_end / steps  # exact division of t_end
        if p["scheme"] == "implicit-euler":
            return [(1.0, dt)] * steps
        r = p["rannacher_steps"]
        return [(1.0, 0.5 * dt)] * r + [(0.5, dt)] * (steps - r // 2)
