"""Verification tests of the scikit-fem heat solver (solvers/continuum/skfem_heat.py).

Every assertion is a numerical fact with a tolerance justified from theory plus a measurement
(measured values quoted in the comments; they are deterministic up to round-off).  Runtime is
kept small: the largest grid has ~46 000 nodes.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.sparse as sp
from heat_faces import transient

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Elasticity, Material, Resolution, SceneError
from pcverify.solvers.continuum.assembly import assemble_q1, split_free, tensor_csr
from pcverify.solvers.continuum.grid import SphereWarp, StructuredGrid, plan_sphere_warp
from pcverify.solvers.continuum.skfem_heat import SkfemHeat

SOLVER = SkfemHeat()


def slope(h, e) -> float:
    """Least-squares slope of log e against log h."""
    return float(np.polyfit(np.log(h), np.log(e), 1)[0])


def order3(f1: float, f2: float, f3: float, r21: float, r32: float) -> tuple[float, float]:
    """Observed order and sign s of a 3-grid study (f1 finest), Celik et al. 2008 fixed point."""
    e21, e32 = f2 - f1, f3 - f2
    s = math.copysign(1.0, e32 / e21)
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)
    for _ in range(200):
        p = abs(math.log(abs(e32 / e21)) + math.log((r21**p - s) / (r32**p - s))) / math.log(r21)
    return p, s


def all_errors(sol, exact) -> float:
    return max(float(np.abs(v["values"] - exact(v["points"])).max()) for v in sol.samples.values())


# ---------------------------------------------------------------------------------------------------
# 1. steady face scene: Q1 reproduces a linear field exactly (error = round-off + solver tolerance)


@pytest.mark.parametrize("n, refine, linear_solver", [(3, 1, "direct"), (4, 2, "direct"), (4, 3, "amg")])
def test_steady_faces_linear_profile(n, refine, linear_solver):
    scene = make_scene("bar-heat-faces")
    sol = SOLVER.solve(scene, Resolution(n, refine), linear_solver=linear_solver)
    err = all_errors(sol, lambda p: 1.0 - p[:, 2] / scene.box.length)
    # Linear functions are in the Q1 space: only round-off (~1e-14 measured) and, for CG,
    # rtol 1e-11 times a condition number ~1e3 remain; 1e-9 leaves two decades of margin.
    assert err < 1e-9
    assert abs(sol.summary["volume_mean"] - 0.5) < 1e-9
    nodes = len(np.unique(np.round(sol.samples["nodes"]["points"], 9), axis=0))
    # the unknowns are the free nodes: the two held faces' nodes are not solved for
    assert sol.status == "ok" and (sol.unknowns == nodes - sol.diagnostics["fixed_nodes"] or refine > 1)
    assert sol.unknowns == sol.diagnostics["free_nodes"]
    if linear_solver == "amg":
        assert sol.work["iterations"] > 0 and sol.diagnostics["max_relative_residual"] < 1e-10


# ---------------------------------------------------------------------------------------------------
# 2. transient face scene against the Fourier series


def _transient_error(refine: int, t_end: float, dt: float, samples=None, **params) -> tuple[float, np.ndarray]:
    scene = make_scene("bar-heat-faces", mode="transient", t_end=t_end, dt=dt)
    samples = samples or scene.sample_sets(5)
    sol = SOLVER.solve(scene, Resolution(2, refine), samples=samples, **params)
    alpha, length = scene.material.diffusivity, scene.box.length
    err = all_errors(sol, lambda p: transient(p[:, 2], t_end, length, alpha, 1.0))
    line = np.concatenate([v["values"] for v in sol.samples.values()])
    assert sol.work["time_steps"] >= round(t_end / dt)
    return err, line


def test_transient_faces_space_order():
    # CN (with Rannacher start), t_end = 1 s, dt = 0.01 s: the CN time error is ~3e-6 (measured
    # 4.3e-4 at dt = 0.125, scaling as dt^2), below 2 % of the finest spatial error.
    refines = [4, 8, 16]
    h = [0.01 / r for r in refines]
    errs = [_transient_error(r, 1.0, 0.01)[0] for r in refines]
    # measured: 2.72e-3, 6.75e-4, 1.61e-4  (slope 2.04)
    assert errs[0] > errs[1] > errs[2]
    assert slope(h, errs) == pytest.approx(2.0, abs=0.2)


def test_transient_faces_time_orders():
    # h = 0.625 mm (n=2, refine 16).  t_end = 2 s; the spatial error at this h is 7.7e-5
    # (measured with dt/8), far below the implicit-Euler errors and < 25 % of the smallest CN error.
    refine, t_end = 16, 2.0
    ie_dt = [0.4, 0.2, 0.1]
    ie = [_transient_error(refine, t_end, dt, scheme="implicit-euler")[0] for dt in ie_dt]
    # measured: 3.21e-2, 1.66e-2, 8.36e-3 (slope 0.97): first order
    assert slope(ie_dt, ie) == pytest.approx(1.0, abs=0.15)

    cn_dt = [0.5, 0.25, 0.125]
    cn = [_transient_error(refine, t_end, dt) for dt in cn_dt]
    fine_err, fine = _transient_error(refine, t_end, cn_dt[-1] / 8)
    assert fine_err < 0.25 * cn[-1][0]  # measured 7.7e-5 vs 3.5e-4: time error dominates
    errs = [c[0] for c in cn]
    # measured against the series: 7.13e-3, 1.68e-3, 3.48e-4 (slope 2.18; the residual spatial error
    # raises the slope by at most ~0.16 at this ratio); against the same-mesh dt/8 solution, which has
    # no spatial error: slope 2.04.
    assert slope(cn_dt, errs) == pytest.approx(2.0, abs=0.2)
    self_errs = [float(np.abs(c[1] - fine).max()) for c in cn]
    assert slope(cn_dt, self_errs) == pytest.approx(2.0, abs=0.1)

    # Plain CN does not damp the sudden start (docs/physics.md, "Continuum references"): at dt = 0.25 s its
    # error is 5.21e-2 (measured), 31x the Rannacher-started 1.68e-3 (at dt = 0.5: 1.17e-1 vs 7.1e-3); assert a
    # factor 10.
    plain, _ = _transient_error(refine, t_end, 0.25, rannacher_steps=0)
    assert plain > 10.0 * errs[1]


# ---------------------------------------------------------------------------------------------------
# 3. patch scene: conforming warp converges cleanly, staircase scatters


def test_patch_conforming_convergence():
    # n = 4, refine 8, 12, 16: h = a/8, a/12, a/16; the warp shell s1 = 0.833 mm is the same at all three
    # levels (m = 2, 3, 4 cells), so the grids are samples of one warp map.
    scene = make_scene("bar-heat-patch")
    centres = np.array([c.centre for c in scene.constraints])
    refines = [8, 12, 16]
    sols = [SOLVER.solve(scene, Resolution(4, r)) for r in refines]
    assert len({round(p["s1"], 12) for s in sols for p in s.diagnostics["patches"]}) == 1
    for s in sols:
        assert s.diagnostics["min_scaled_jacobian"] > 0
        assert abs(s.diagnostics["volume_error"]) < 1e-12
    h = [s.resolution["h"] for s in sols]
    vm = [s.summary["volume_mean"] for s in sols]
    p, sign = order3(vm[2], vm[1], vm[0], h[1] / h[2], h[0] / h[1])
    # measured: 0.3175680, 0.3175864, 0.3175909: monotone, p = 2.97 (theory: 2 asymptotically; the
    # leading h^2 coefficient is evidently small at these levels, so the observed order is higher)
    assert sign > 0 and p >= 1.8
    r21 = h[1] / h[2]
    ext = (r21**p * vm[2] - vm[1]) / (r21**p - 1)
    gci = 1.25 * abs((vm[2] - vm[1]) / vm[2]) / (r21**p - 1)
    # measured: extrapolated 0.3175942, GCI_fine 1.3e-5 (relative), |ext - fine| 3.3e-6
    assert gci < 3e-5 and abs(ext - vm[2]) < 1e-5

    pts = np.vstack([sols[0].samples[k]["points"] for k in ("front_top_edge", "bottom_back_edge")])
    far = np.linalg.norm(pts[:, None, :] - centres[None], axis=2).min(axis=1) >= 2 * 1e-3
    vals = [np.concatenate([s.samples[k]["values"] for k in ("front_top_edge", "bottom_back_edge")])[far]
            for s in sols]
    # RMS and max of successive differences over the 17 edge points >= 2 rho from the patches; order from
    # their ratio with the same fixed point (pointwise 3-grid orders are ill-conditioned where an error
    # changes sign).  Measured: RMS 4.01e-5 -> 9.95e-6 (p = 2.95), max 7.35e-5 -> 1.81e-5 (p = 2.97).
    for norm in (lambda d: float(np.sqrt(np.mean(d**2))), lambda d: float(np.abs(d).max())):
        d21, d32 = norm(vals[2] - vals[1]), norm(vals[1] - vals[0])
        p_edges, _ = order3(0.0, d21, d21 + d32, h[1] / h[2], h[0] / h[1])
        assert d21 < d32 and p_edges >= 1.8


def test_patch_staircase_scatters():
    scene = make_scene("bar-heat-patch")
    vm = [SOLVER.solve(scene, Resolution(4, r), patch="staircase").summary["volume_mean"] for r in (6, 8, 10)]
    # measured: 0.320729, 0.320482, 0.319270 (refine 12: 0.319859, non-monotone).  A second-order
    # sequence would shrink the differences by (1/64 - 1/100)/(1/36 - 1/64) = 0.46; staircase grows them
    # by 4.9, so Richardson does not apply.
    ratio = abs(vm[2] - vm[1]) / abs(vm[1] - vm[0])
    assert ratio > 1.0
    conforming = 0.317594  # Richardson-extrapolated conforming volume mean (GCI 1.3e-5, previous test)
    assert abs(vm[2] - conforming) > 1e-3  # measured 1.7e-3


# ---------------------------------------------------------------------------------------------------
# 4. paper scene: point constraints, bulk level tends to 1/3 at first order


@pytest.mark.parametrize("placement", ["back-edge", "diagonal"])
def test_paper_bulk_tends_to_one_third(placement):
    scene = make_scene("bar-heat-paper", placement=placement)
    lattice = [SOLVER.solve(scene, Resolution(n)).summary["bulk_median"] for n in (2, 3, 4)]
    # measured (back-edge): 0.2706, 0.3180, 0.3189: below 1/3 and rising
    assert lattice[0] < lattice[1] < lattice[2] < 1 / 3
    refines = [1, 2, 4]
    sols = [SOLVER.solve(scene, Resolution(4, r)) for r in refines]
    med = np.array([s.summary["bulk_median"] for s in sols])
    h = [s.resolution["h"] for s in sols]
    gap = 1 / 3 - med
    assert np.all(gap > 0) and np.all(np.diff(gap) < 0)
    # measured gaps 1.447e-2, 7.42e-3, 3.76e-3: slope 0.97.  With gap = C1 h + C2 h^2 the local slope
    # at h = a is 0.96, so 1 +- 0.1 covers the h^2 term with margin.
    assert slope(h, gap) == pytest.approx(1.0, abs=0.1)
    richardson = 2 * med[2] - med[1]  # p = 1 extrapolation: measured 0.33325 (8.6e-5 from 1/3)
    assert abs(richardson - 1 / 3) < 2e-4
    assert gap[2] < 4e-3  # measured 3.76e-3 at h = a/4


# ---------------------------------------------------------------------------------------------------
# 5. constraints hold exactly; parameters are checked


def test_fixed_nodes_hold_their_values():
    paper = SOLVER.solve(make_scene("bar-heat-paper"), Resolution(3, 2))
    nodes = paper.samples["nodes"]
    pts, vals = nodes["points"], nodes["values"]
    for corner, value in (((0.0, 0.01, 0.0), 1.0), ((0.01, 0.0, 0.0), 0.0), ((0.01, 0.0, 0.03), 0.0)):
        i = int(np.argmin(np.linalg.norm(pts - np.array(corner), axis=1)))
        assert vals[i] == value  # exactly: condensed, not penalised
    patch = SOLVER.solve(make_scene("bar-heat-patch"), Resolution(4, 3))
    edge = patch.samples["front_top_edge"]
    assert edge["values"][0] == pytest.approx(1.0, abs=1e-14)  # hot corner inside the patch
    inside = np.array([[0.0, 0.01 - 0.5e-3, 0.3e-3]])  # 0.58 mm from the hot corner, inside rho = 1 mm
    again = SOLVER.solve(make_scene("bar-heat-patch"), Resolution(4, 3), samples={"p": inside})
    assert again.samples["p"]["values"][0] == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize(
    "params, name",
    [({"scheme": "rk4"}, "scheme"), ({"rannacher_steps": 3}, "rannacher_steps"), ({"rannacher_steps": -2},
     "rannacher_steps"), ({"patch": "round"}, "patch"), ({"linear_solver": "lu"}, "linear_solver"),
     ({"cg_rtol": 0.0}, "cg_rtol"), ({"direct_max_unknowns": 0}, "direct_max_unknowns"), ({"foo": 1}, "foo")],
)
def test_bad_parameters_raise(params, name):
    scene = make_scene("bar-heat-faces", mode="transient", t_end=0.1, dt=0.05)
    with pytest.raises(SceneError, match=name):
        SOLVER.solve(scene, Resolution(2), **params)


def test_bad_scene_settings_raise():
    scene = make_scene("bar-heat-faces", mode="transient", t_end=1.0, dt=0.3)
    with pytest.raises(SceneError, match="dt"):
        SOLVER.solve(scene, Resolution(2))
    short = make_scene("bar-heat-faces", mode="transient", t_end=0.1, dt=0.05)
    with pytest.raises(SceneError, match="rannacher_steps"):
        SOLVER.solve(short, Resolution(2), rannacher_steps=6)
    both = Material("both", 2700.0, 237.0, 897.0, 70e9, 0.33)
    coupled = dataclasses.replace(scene, physics=frozenset({"conduction", "elasticity"}), elasticity=Elasticity(),
                                  material=both)
    ok, why = SOLVER.supports(coupled)
    assert not ok and "conduction" in why
    assert SOLVER.supports(make_scene("bar-heat-patch")) == (True, "")


def test_grid_warp_properties():
    # the warp keeps the corner's faces planar, puts the shell on the sphere and inverts exactly
    grid = StructuredGrid.lattice(np.array([0.01, 0.01, 0.03]), 4, 6)
    warp = plan_sphere_warp((0.0, 0.01, 0.0), 1e-3, grid.h, grid.patch_limit((0.0, 0.01, 0.0), []))
    assert isinstance(warp, SphereWarp) and warp.min_slope() > 0
    ref = grid.reference_points.copy()
    inside = grid.add_warp(warp)
    r = np.linalg.norm(grid.points[inside] - np.array(warp.centre), axis=1)
    assert r.max() == pytest.approx(1e-3, rel=1e-12)
    on_face = ref[:, 0] == 0.0
    assert np.all(grid.points[on_face, 0] == 0.0)
    assert np.allclose(warp.inverse(grid.points), ref, atol=1e-15)
    assert grid.min_scaled_jacobian() > 0


# ---------------------------------------------------------------------------------------------------
# 6. fast structured assembly (solvers/continuum/assembly.py) is scikit-fem's assembly


def _skfem_reference(grid):
    from skfem import Basis, ElementHex1, MeshHex
    from skfem.models.poisson import laplace, mass, unit_load

    basis = Basis(MeshHex(np.ascontiguousarray(grid.points.T), grid.cells.astype(np.int32)), ElementHex1(),
                  intorder=2)
    return laplace.assemble(basis).tocsr(), mass.assemble(basis).tocsr(), unit_load.assemble(basis)


@pytest.mark.parametrize("warped", [False, True])
def test_tensor_assembly_equals_skfem(warped):
    grid = StructuredGrid.lattice(np.array([0.01, 0.01, 0.03]), 4, 3)
    if warped:  # the three conforming patch warps of bar-heat-patch
        scene = make_scene("bar-heat-patch")
        centres = [c.centre for c in scene.constraints]
        for c in scene.constraints:
            grid.add_warp(plan_sphere_warp(c.centre, c.radius, grid.h, grid.patch_limit(c.centre, centres)))
    ops = assemble_q1(grid, with_mass=True)
    stiff, mss, load = _skfem_reference(grid)
    assert (ops.warped_cells > 0) == warped
    # Kronecker sums of scikit-fem's 1-D P1 matrices (+ scikit-fem on the warped cells) are the same
    # numbers summed in another order: round-off only (measured 1.7e-15 .. 2.6e-15 relative).
    for mine, theirs in ((ops.stiffness, stiff), (ops.mass, mss)):
        assert abs(mine - theirs).max() <= 1e-12 * abs(theirs).max()
    assert np.abs(ops.weights - load).max() <= 1e-12 * np.abs(load).max()
    # On box cells the Q1 Laplacian couples no two nodes joined by a cell edge (-4/9 + 2/9 + 2/9 = 0): the
    # 27-point stencil has 6 exact zeros per interior row, which the fast assembly leaves out.
    interior = grid.shape[0] - 2, grid.shape[1] - 2, grid.shape[2] - 2
    dropped = stiff.nnz - ops.stiffness.nnz
    assert dropped >= 6 * int(np.prod(interior)) * (0.9 if warped else 1.0)
    # full_pattern (used with SuperLU, whose ordering fills in far more on the 21-point pattern) stores the
    # whole 27-point pattern, zeros included: (3m - 2) neighbour pairs per axis
    full = assemble_q1(grid, full_pattern=True).stiffness
    assert full.nnz == int(np.prod([3 * m - 2 for m in grid.shape]))
    assert abs(full - stiff).max() <= 1e-12 * abs(stiff).max()


def test_tensor_csr_is_kronecker_sum():
    rng = np.random.default_rng(7)

    def tri(m):
        return sp.diags([rng.normal(size=m - 1), rng.normal(size=m), rng.normal(size=m - 1)], [-1, 0, 1]).tocsr()

    terms = [(tri(4), tri(5), tri(6)), (tri(4), tri(5), tri(6))]
    mine = tensor_csr(terms, drop_rtol=0.0)
    ref = sum(sp.kron(a, sp.kron(b, c)) for a, b, c in terms).tocsr()
    # with random entries no product vanishes: the full pattern, (3m - 2) neighbour pairs per axis
    assert mine.has_sorted_indices and mine.nnz == ref.nnz == (3 * 4 - 2) * (3 * 5 - 2) * (3 * 6 - 2)
    assert abs(mine - ref).max() <= 1e-14 * abs(ref).max()


@pytest.mark.parametrize("fraction", [0.7, 1.0])
def test_split_free_is_fancy_indexing(fraction: float):
    """Also with every row free (the shortcut that returns the matrix itself, no copy)."""
    rng = np.random.default_rng(3)
    a = sp.random(60, 60, density=0.2, random_state=rng, format="csr") + sp.eye(60)
    free = rng.random(60) < fraction
    ff, fb = split_free(a, free)
    # exactly scipy's a[free][:, free] and a[free][:, ~free] (same entries, same order)
    assert (ff != a[free][:, free]).nnz == 0 and (fb != a[free][:, ~free]).nnz == 0
    assert ff.shape == (free.sum(), free.sum()) and fb.shape == (free.sum(), (~free).sum())


def test_amg_solve_is_bit_reproducible():
    # the AMG set-up uses no random numbers ('local' Jacobi weighting): two solves agree bit for bit
    scene = make_scene("bar-heat-patch")
    a, b = (SOLVER.solve(scene, Resolution(4, 4), linear_solver="amg") for _ in range(2))
    assert a.work["iterations"] > 0
    for name in a.samples:
        assert np.array_equal(a.samples[name]["values"], b.samples[name]["values"])
    assert a.summary == b.summary
