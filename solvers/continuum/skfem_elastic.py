"""scikit-fem linear elasticity of the bar: static (supports, clamps) and modal analysis, Q1 or Q2 hexahedra.

The continuum reference for the elastic scenes: K and M assembled once on the unit cube and scattered, rigid
motions held by the force-free "3-2-1" set, SuperLU or AMG-CG by size, ARPACK shift-invert for the modes
(docs/physics.md, "Continuum references", scikit-fem).
"""

from __future__ import annotations

import functools
import time
from typing import Any

import numpy as np
import scipy.sparse as sp
import skfem
from scipy.sparse.linalg import LinearOperator, eigsh
from skfem import Basis, BilinearForm, ElementVector, FacetBasis, Functional, MeshHex
from skfem.helpers import dot
from skfem.models.elasticity import lame_parameters, linear_elasticity

from pcverify.scene import FaceClamp, FaceSupport, Resolution, Scene, SceneError
from pcverify.solvers.continuum.grid import HEX_CORNERS, StructuredGrid
from pcverify.solvers.continuum.linear_solver import SpdSolver, smoothed_aggregation
from pcverify.solvers.continuum.parameters import SKFEM_ELASTIC
from pcverify.solvers.continuum.work import ELASTIC_BYTES_PER_DOF, grid_nodes
from pcverify.solvers.modes import classify, cut_is_complete, kind_summary, symmetric_lateral
from pcverify.solvers.protocol import Solution, WorkEstimate, effective_params

PARAMETERS = SKFEM_ELASTIC

ELEMENTS = {"q1": ("ElementHex1", 2, 1), "q2": ("ElementHex2", 4, 2)}  # class, intorder, degree


def _linear_solver(a: sp.spmatrix, method: str, rtol: float, near_null: np.ndarray | None = None) -> SpdSolver:
    """SuperLU or CG with a smoothed-aggregation AMG preconditioner on the 3x3-block matrix, `near_null`
    (the rigid-body modes) as its near-nullspace."""

    def amg(mat: sp.csr_matrix) -> Any:
        blocked = mat.shape[0] % 3 == 0
        # theta = 0.05: the wide Q2 stencil otherwise makes a single huge-aggregate coarse level (33
        # iterations at 11k unknowns; 21 with it); the rigid-body modes are exact, no candidate improvement
        return smoothed_aggregation(mat.tobsr(blocksize=(3, 3)) if blocked else mat, B=near_null,
                                    symmetry="symmetric", max_coarse=500, strength=("symmetric", {"theta": 0.05}),
                                    improve_candidates=None)

    return SpdSolver(a, method, rtol, amg)


@functools.lru_cache(maxsize=16)
def unit_cell_matrices(element_name: str, intorder: int, lam: float, mu: float, rho: float):
    """Element stiffness and mass matrices (local dof order) of the unit cube, by scikit-fem: on a cube of side h
    K_e(h) = h K_e(1) and M_e(h) = h^3 M_e(1).  Cached: the 81 x 81 Q2 forms cost about a second each."""
    @BilinearForm
    def vmass(u, v, _w):
        return rho * dot(u, v)

    cube = MeshHex(np.ascontiguousarray(HEX_CORNERS.T.astype(float)), np.arange(8, dtype=np.int32)[:, None])
    one = Basis(cube, ElementVector(getattr(skfem, element_name)()), intorder=intorder)
    local = one.element_dofs[:, 0]
    ke = linear_elasticity(lam, mu).assemble(one).toarray()[np.ix_(local, local)]
    me = vmass.assemble(one).toarray()[np.ix_(local, local)]
    return ke, me


def scatter_uniform(ke: np.ndarray, element_dofs: np.ndarray, ndof: int) -> sp.csr_matrix:
    """Global matrix of a grid of identical, translated cells (every unwarped cell of `StructuredGrid`): the
    element matrix `ke` scattered with the dof map `element_dofs` (n_local, n_cells)."""
    nloc = element_dofs.shape[0]
    rows = np.repeat(element_dofs, nloc, axis=0)  # entry (i, j) of cell c sits at row i * nloc + j
    cols = np.tile(element_dofs, (nloc, 1))
    data = np.broadcast_to(ke.reshape(-1, 1), rows.shape)
    mat = sp.coo_matrix((data.ravel(), (rows.ravel(), cols.ravel())), shape=(ndof, ndof)).tocsr()
    mat.sum_duplicates()
    return mat


def mode_shape(phi: np.ndarray) -> np.ndarray:
    """A mode scaled to max |u| = 1 with a sign fixed by the mode itself (an eigensolver returns either sign,
    by the machine's round-off): the first entry of the largest magnitude, magnitudes rounded to 1e-8 of the
    largest so that entries equal by symmetry are one tie, is positive."""
    size = np.abs(phi)
    first = int(np.argmax(np.round(size / size.max(), 8)))
    return phi / (size.max() * np.sign(phi[first]))


def rigid_body_modes(locs: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The six rigid-body displacement fields at interleaved vector dofs: (3 N, 6), columns unit-scaled."""
    n = locs.shape[1]
    d = (locs - centre[:, None]) / np.abs(locs - centre[:, None]).max()
    b = np.zeros((3 * n, 6))
    for c in range(3):
        b[c::3, c] = 1.0
    x, y, z = d
    b[0::3, 3], b[1::3, 3] = -y, x  # rotation about z
    b[1::3, 4], b[2::3, 4] = -z, y  # about x
    b[0::3, 5], b[2::3, 5] = z, -x  # about y
    return b


class SkfemElastic:
    """Linear elasticity of the bar with scikit-fem Q1/Q2 hexahedra: static supports and modal analysis."""

    name = "skfem-elastic"
    kind = "continuum"
    parameters = PARAMETERS

    def estimate(self, scene: Scene, resolution: Resolution, **params: Any) -> WorkEstimate:
        """Degrees of freedom (3 per node of the Q1 or Q2 grid) and memory of the solve."""
        p = effective_params(self, params)
        degree = ELEMENTS[p["element"]][2]
        dofs = 3 * grid_nodes(scene, Resolution(resolution.n, resolution.refine * degree))
        return WorkEstimate(unknowns=dofs, steps=1, bytes=ELASTIC_BYTES_PER_DOF * dofs)

    def supports(self, scene: Scene) -> tuple[bool, str]:
        if "elasticity" not in scene.physics:
            return False, f"skfem-elastic does linear elasticity only; scene needs {sorted(scene.physics)}"
        extra = set(scene.physics) - {"elasticity", "modes"}
        if extra:
            return False, (f"skfem-elastic is linear elastic (static or modal); it does not model {sorted(extra)} "
                           "(the fracture scene is left to the particle solvers)")
        if not any(isinstance(c, (FaceSupport, FaceClamp)) for c in scene.constraints):
            return False, "an unsupported elastic bar is singular: no FaceSupport or FaceClamp"
        other = [type(c).__name__ for c in scene.constraints if not isinstance(c, (FaceSupport, FaceClamp))]
        if other:
            return False, f"skfem-elastic handles FaceSupport and FaceClamp only, not {other}"
        if "modes" in scene.physics and any(c.displacement != 0.0 for c in scene.constraints
                                            if isinstance(c, FaceSupport)):
            return False, "modal analysis needs homogeneous constraints (a FaceSupport displacement is set)"
        return True, ""

    # -- set-up ------------------------------------------------------------------------------------

    @staticmethod
    def _dirichlet(scene: Scene, locs: np.ndarray, extent: np.ndarray, h: float) -> tuple[np.ndarray, dict]:
        """Prescribed value per vector dof (NaN = free), rigid-body constraints added where needed."""
        ndof = 3 * locs.shape[1]
        fixed = np.full(ndof, np.nan)
        tol = 1e-9 * h
        on_face = {}
        for face in ("x0", "xW", "y0", "yH", "z0", "zL"):
            axis = "xyz".index(face[0])
            at = 0.0 if face[1] == "0" else extent[axis]
            on_face[face] = np.flatnonzero(np.abs(locs[axis] - at) <= tol)
        diag: dict[str, Any] = {}
        normals = set()
        for c in scene.constraints:
            nodes = on_face[c.face]
            axis = "xyz".index(c.face[0])
            if isinstance(c, FaceClamp):
                for comp in range(3):
                    fixed[3 * nodes + comp] = 0.0
                normals.update(range(3))
            else:
                fixed[3 * nodes + axis] = c.displacement
                normals.add(axis)
        if normals == {0, 1, 2}:  # supports normal to every axis (a clamp, or rollers all round): no rigid mode
            return fixed, diag
        if normals != {2}:
            raise SceneError(f"skfem-elastic: supports normal to axes {sorted('xyz'[a] for a in normals)} leave "
                             "rigid-body modes it does not remove; allowed: supports normal to z only, to every "
                             "axis, or a FaceClamp")
        z0 = on_face["z0"]
        corner_a = z0[np.flatnonzero((np.abs(locs[0, z0]) <= tol) & (np.abs(locs[1, z0]) <= tol))]
        corner_b = z0[np.flatnonzero((np.abs(locs[0, z0] - extent[0]) <= tol) & (np.abs(locs[1, z0]) <= tol))]
        fixed[3 * corner_a + 0] = 0.0
        fixed[3 * corner_a + 1] = 0.0
        fixed[3 * corner_b + 1] = 0.0
        diag["rigid_constraints"] = "u_x = u_y = 0 at (0, 0, 0); u_y = 0 at (W, 0, 0)"
        diag["_rigid_dofs"] = np.array([3 * corner_a[0], 3 * corner_a[0] + 1, 3 * corner_b[0] + 1])
        return fixed, diag

    # -- solve --------------------------------------------------------------------------------------

    def solve(self, scene: Scene, resolution: Resolution, samples: dict[str, np.ndarray] | None = None,
              **params: Any) -> Solution:
        wall0 = time.perf_counter()
        p = effective_params(self, params)
        ok, why = self.supports(scene)
        if not ok:
            raise SceneError(why)
        n, refine = int(resolution.n), int(resolution.refine)
        extent = scene.box.extent
        grid = StructuredGrid.lattice(extent, n, refine)
        cls_name, intorder, degree = ELEMENTS[p["element"]]

        t0 = time.perf_counter()
        mesh = MeshHex(np.ascontiguousarray(grid.points.T), grid.cells.astype(np.int32))
        element = getattr(skfem, cls_name)()
        # dof maps and probes only: the one-point rule keeps these bases cheap (K and M use `intorder`)
        basis = Basis(mesh, ElementVector(element), intorder=1)
        sbasis = Basis(mesh, element, intorder=1)
        locs = sbasis.doflocs
        mat = scene.material
        lam, mu = lame_parameters(mat.youngs_modulus, mat.poisson_ratio)
        rho = mat.density

        ke, me = unit_cell_matrices(cls_name, intorder, float(lam), float(mu), float(rho))
        stiff = scatter_uniform(grid.h * ke, basis.element_dofs, basis.N)
        mass = scatter_uniform(grid.h**3 * me, basis.element_dofs, basis.N) if "modes" in scene.physics else None
        assembly_s = time.perf_counter() - t0

        fixed, diag = self._dirichlet(scene, locs, extent, grid.h)
        rigid_dofs = diag.pop("_rigid_dofs", None)
        is_fixed = ~np.isnan(fixed)
        ndof = int(basis.N)
        method = p["linear_solver"]
        if method == "auto":
            limit = p["modal_direct_max_unknowns"] if "modes" in scene.physics else p["direct_max_unknowns"]
            method = "direct" if ndof <= limit else "amg"
        near_null = rigid_body_modes(locs, 0.5 * extent)

        t1 = time.perf_counter()
        summary: dict[str, Any] = {}
        if "modes" in scene.physics:
            u, extra, solver = self._modes(scene, stiff, mass, is_fixed, method, p, near_null, locs, extent,
                                           grid.h / degree)
            solve_s = time.perf_counter() - t1
            summary.update(extra.pop("summary"))
            diag.update(extra)
        else:
            u, solver = self._static(stiff, fixed, is_fixed, method, p, near_null)
            solve_s = time.perf_counter() - t1
            summary.update(self._static_summary(scene, mesh, basis, element, intorder, stiff, u, locs, extent,
                                                grid.h))
            if rigid_dofs is not None:
                diag["rigid_constraint_reactions_N"] = (stiff @ u)[rigid_dofs]

        if samples is None:
            samples = scene.sample_sets(n)
        out: dict[str, dict[str, np.ndarray]] = {}
        for key, pts in samples.items():
            pts = np.asarray(pts, dtype=float).reshape(-1, 3)
            if np.any(pts < -1e-9 * grid.h) or np.any(pts > extent + 1e-9 * grid.h):
                raise SceneError(f"samples[{key!r}]: a sample point lies outside the box; allowed: inside the bar")
            probe = sbasis.probes(np.clip(pts, 0.0, extent).T)
            out[key] = {"points": pts, "values": np.stack([probe @ u[c::3] for c in range(3)], axis=1)}
        diag.update({"linear_solver": method, "max_relative_residual": solver.worst_residual,
                     "fixed_dofs": int(is_fixed.sum()), "element": p["element"], "intorder": intorder})
        wall = time.perf_counter() - wall0
        post_s = wall - (t1 - wall0) - solve_s
        return Solution(
            scene=scene.name, solver=self.name, params=p,
            resolution={"n": n, "refine": refine, "h": grid.h, "nodes": len(grid.points)},
            samples=out, unknowns=int(np.count_nonzero(~is_fixed)), wall_s=wall, status="ok",
            quantity="mode-1 shape (max |u| = 1)" if "modes" in scene.physics else "u (m)",
            work={"unknowns": int(np.count_nonzero(~is_fixed)), "iterations": int(solver.iterations),
                  "solves": int(solver.solves),
                  "assembly_s": assembly_s, "solve_s": solve_s, "postprocess_s": post_s},
            summary=summary, diagnostics=diag,
        )

    @staticmethod
    def _static(stiff, fixed, is_fixed, method, p, near_null):
        """Lifted Dirichlet problem with the constrained rows/columns replaced by their diagonal, solved for
        prescribed displacements scaled to unit size and scaled back (linear: exact; keeps CG's norms away
        from underflow whatever the load's magnitude)."""
        g = np.where(is_fixed, fixed, 0.0)
        scale = float(np.max(np.abs(g))) or 1.0
        g = g / scale
        d = stiff.diagonal()
        rhs = -(stiff @ g)
        rhs[is_fixed] = d[is_fixed] * g[is_fixed]
        keep = sp.diags((~is_fixed).astype(float))
        a = (keep @ stiff @ keep + sp.diags(np.where(is_fixed, d, 0.0))).tocsr()
        a.eliminate_zeros()
        solver = _linear_solver(a, method, p["cg_rtol"], near_null)
        u = solver.solve(rhs)
        u[is_fixed] = g[is_fixed]
        return u * scale, solver

    @staticmethod
    def _static_summary(scene, mesh, basis, element, intorder, stiff, u, locs, extent, h) -> dict[str, Any]:
        """E_eff from the reaction on face zL, nu_eff from the face-averaged lateral displacements."""
        supports = {c.face: c.displacement for c in scene.constraints if isinstance(c, FaceSupport)}
        out: dict[str, Any] = {}
        if "zL" not in supports or "z0" not in supports:
            return out
        length = extent[2]
        strain = (supports["zL"] - supports["z0"]) / length
        react = stiff @ u
        top = np.flatnonzero(np.abs(locs[2] - extent[2]) <= 1e-9 * h)
        force = float(react[3 * top + 2].sum())
        area = extent[0] * extent[1]
        out["reaction_force"] = force
        out["axial_strain"] = strain
        out["E_eff"] = force / area / strain

        @Functional
        def comp_x(w):
            return w["u"][0]

        @Functional
        def comp_y(w):
            return w["u"][1]

        @Functional
        def one(w):
            return 1.0 + 0.0 * w.x[0]

        means = {}
        for face, axis, form in (("x0", 0, comp_x), ("xW", 0, comp_x), ("y0", 1, comp_y), ("yH", 1, comp_y)):
            at = 0.0 if face[1] == "0" else extent[axis]
            facets = mesh.facets_satisfying(lambda x, a=axis, v=at: np.abs(x[a] - v) <= 1e-9 * h)
            fb = FacetBasis(mesh, ElementVector(element), facets=facets, intorder=intorder)
            means[face] = form.assemble(fb, u=fb.interpolate(u)) / one.assemble(fb)
        lateral = 0.5 * ((means["xW"] - means["x0"]) / extent[0] + (means["yH"] - means["y0"]) / extent[1])
        out["lateral_strain"] = float(lateral)
        out["nu_eff"] = float(-lateral / strain)
        return out

    @staticmethod
    def _modes(scene, stiff, mass, is_fixed, method, p, near_null, locs, extent, unit):
        """Lowest `scene.elasticity.modes` eigenpairs of K phi = omega^2 M phi on the free dofs, classified."""
        free = np.flatnonzero(~is_fixed)
        kff = stiff[free][:, free].tocsr()
        mff = mass[free][:, free].tocsr()
        k = int(scene.elasticity.modes)
        if k + 2 >= free.size - 1:
            raise SceneError(f"modes={k} is out of range; allowed: integer in [1, {free.size - 4}] at this "
                             "resolution")
        solver = _linear_solver(kff, method, p["cg_rtol"],
                               near_null[free] if free.size % 3 == 0 else None)
        op = LinearOperator(kff.shape, matvec=solver.solve, dtype=float)
        v0 = np.random.default_rng(20261121).standard_normal(free.size)
        k_solve = k + 2  # spare modes: widened until the degenerate cluster at the cut is complete
        while True:
            vals, vecs = eigsh(kff, k=k_solve, M=mff, sigma=0.0, which="LM", OPinv=op, v0=v0,
                               ncv=min(free.size - 1, max(2 * k_solve + 1, 20)))
            order = np.argsort(vals)
            vals, vecs = vals[order], vecs[:, order]
            if cut_is_complete(vals, k) or 2 * k_solve >= free.size - 1:
                break
            k_solve *= 2
        if np.any(vals <= 0):
            raise ArithmeticError(f"non-positive eigenvalue {vals.min():.3g}: the clamped bar is not stable")
        phi = np.zeros((stiff.shape[0], k_solve))
        phi[free] = vecs
        cls = classify(phi, vals, mass, locs.T, extent, unit, energy=(symmetric_lateral,)).first(k)
        vals = vals[:k]
        freqs = np.sqrt(vals) / (2.0 * np.pi)
        # relative eigen-residual ||K phi - w2 M phi|| / ||K phi|| of every returned pair
        kphi = stiff[free] @ cls.phi
        mphi = mass[free] @ cls.phi
        resid = np.linalg.norm(kphi - mphi * vals[None, :], axis=0) / np.linalg.norm(kphi, axis=0)
        summary: dict[str, Any] = {"frequencies_hz": freqs, "mode_kinds": cls.kinds}
        summary.update(kind_summary(cls.kinds, freqs))
        extra = {"summary": summary, "mode_parities": cls.parities, "axial_mass_fraction": cls.shares["axial"],
                 "eigen_residuals": resid}
        return mode_shape(cls.phi[:, 0]), extra, solver
