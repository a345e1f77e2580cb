"""Benchmark: continuum steady solves at fixed unknowns (scikit-fem Q1 FEM, FiPy FV), issue 7 item 6.

Sizes: the refined lattice of n = 4 at refine 5 / 10 / 20, i.e. 11 776 / 87 451 / 673 501 unknowns for both
solvers (skfem: grid nodes; FiPy: the node-centred dual cells, one per node).  Scene bar-heat-faces (plain
grid) for both; bar-heat-patch for skfem at the largest size (the warped conforming-patch band goes through
scikit-fem's general assembly).  One side-by-side pair measures the assembly speed-up at ~87 000 nodes:
scikit-fem's general assembly of the same Q1 matrix against the tensor-product assembly.  Another measures the
FiPy solve with the fast set-up of solvers/continuum/fipy_fast.py against FiPy's plain Grid3D / DiffusionTerm
set-up (the same matrix bit for bit) at 87 451 and 673 501 cells, rounds interleaved, ratio in extra_info.

Timed by pytest-benchmark (`pcverify bench --tests tests/bench/test_bench_continuum.py`); a small solve
warms imports and the numba cache outside the timing.  extra_info carries the work counters (unknowns,
iterations) and where the time went (assembly_s, solve_s, of the last round).  Under the default
`--benchmark-disable` (the plain test suite) the ~673 000-unknown cases are skipped to keep the suite short.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.continuum.assembly import assemble_q1
from pcverify.solvers.continuum.fipy_heat import FipyHeat
from pcverify.solvers.continuum.grid import StructuredGrid
from pcverify.solvers.registry import get_solver

SIZES = {5: 11_776, 10: 87_451, 20: 673_501}  # refine of n = 4 -> nodes (FiPy: cells); unknowns exclude held ones
LARGE = 20


def _case(benchmark, solver_name: str, scene_name: str, refine: int, rounds: int) -> None:
    if benchmark.disabled and refine >= LARGE:
        pytest.skip("~673 000 unknowns: run only when benchmarking (pcverify bench)")
    solver, scene = get_solver(solver_name), make_scene(scene_name)
    solver.solve(scene, Resolution(4, 3))  # warm-up outside the timing (imports, numba cache)
    sol = benchmark.pedantic(solver.solve, args=(scene, Resolution(4, refine)), rounds=rounds, iterations=1)
    benchmark.extra_info.update(
        solver=solver_name, scene=scene_name, n=4, refine=refine, unknowns=sol.unknowns,
        assembly_s=sol.work["assembly_s"], solve_s=sol.work["solve_s"], iterations=sol.work["iterations"],
        linear_solver=sol.diagnostics.get("linear_solver", sol.diagnostics.get("linear_method")),
    )
    held = sol.diagnostics.get("fixed_nodes", sol.diagnostics.get("fixed_cells", 0))
    assert sol.unknowns == SIZES[refine] - held and sol.status == "ok"
    if scene_name == "bar-heat-faces":  # the steady face scene is linear in z: both methods reproduce it
        assert sol.summary["volume_mean"] == pytest.approx(0.5, abs=1e-8)


@pytest.mark.parametrize("refine", [5, 10, 20])
@pytest.mark.parametrize("solver_name", ["skfem", "fipy"])
def test_bench_steady_faces(benchmark, solver_name: str, refine: int) -> None:
    _case(benchmark, solver_name, "bar-heat-faces", refine, rounds=3 if refine < LARGE else 3)


class _StockFipy(FipyHeat):
    """FipyHeat with FiPy's plain Grid3D / DiffusionTerm set-up (the same matrix, bit for bit: tests/test_fipy_fast)."""

    def _assemble(self, *args, **kwargs):
        return super()._assemble(*args, stock=True, **kwargs)


@pytest.mark.parametrize("refine", [10, 20])
def test_bench_fipy_setup_stock_vs_fast(benchmark, refine: int) -> None:
    """The FiPy steady solve with the fast set-up (timed) against the plain FiPy set-up, rounds interleaved.

    The plain solve runs in each round's untimed setup (perf_counter), so both see the same machine load;
    extra_info: best-of-3 of each, their ratio, and each one's assembly / solve split (best round).
    """
    if benchmark.disabled and refine >= LARGE:
        pytest.skip("~673 000 unknowns: run only when benchmarking (pcverify bench)")
    scene, res = make_scene("bar-heat-faces"), Resolution(4, refine)
    fast, stock = FipyHeat(), _StockFipy()
    fast.solve(scene, Resolution(4, 3))  # warm-up outside the timing
    stock_runs: list[tuple[float, object]] = []

    def setup():
        t0 = time.perf_counter()
        sol = stock.solve(scene, res)
        stock_runs.append((time.perf_counter() - t0, sol))

    fast_runs: list[tuple[float, object]] = []

    def run():
        t0 = time.perf_counter()
        sol = fast.solve(scene, res)
        fast_runs.append((time.perf_counter() - t0, sol))
        return sol

    benchmark.pedantic(run, setup=setup, rounds=3, iterations=1)
    (t_stock, s_stock), (t_fast, s_fast) = min(stock_runs, key=lambda r: r[0]), min(fast_runs, key=lambda r: r[0])
    benchmark.extra_info.update(
        solver="fipy", scene="bar-heat-faces", n=4, refine=refine, unknowns=s_fast.unknowns,
        stock_best_s=t_stock, fast_best_s=t_fast, ratio_stock_over_fast=t_stock / t_fast,
        stock_assembly_s=s_stock.work["assembly_s"], stock_solve_s=s_stock.work["solve_s"],
        fast_assembly_s=s_fast.work["assembly_s"], fast_solve_s=s_fast.work["solve_s"],
    )
    assert s_fast.unknowns == s_stock.unknowns == SIZES[refine]
    for name, smp in s_stock.samples.items():  # the same matrix and AMG seed: the same field
        assert np.array_equal(s_fast.samples[name]["values"], smp["values"]), name


def test_bench_skfem_steady_patch_large(benchmark) -> None:
    _case(benchmark, "skfem", "bar-heat-patch", LARGE, rounds=3)


def _skfem_general(grid: StructuredGrid):
    from skfem import Basis, ElementHex1, MeshHex
    from skfem.models.poisson import laplace

    basis = Basis(MeshHex(np.ascontiguousarray(grid.points.T), grid.cells.astype(np.int32)), ElementHex1(),
                  intorder=2)
    return laplace.assemble(basis).tocsr()


@pytest.mark.parametrize("method", ["skfem-general", "tensor"])
def test_bench_q1_assembly(benchmark, method: str) -> None:
    grid = StructuredGrid.lattice(np.array([0.01, 0.01, 0.03]), 4, 10)  # 87 451 nodes
    assemble_q1(StructuredGrid.lattice(np.array([0.01, 0.01, 0.03]), 2, 2))  # numba cache warm-up
    fn = _skfem_general if method == "skfem-general" else (lambda g: assemble_q1(g).stiffness)
    mat = benchmark.pedantic(fn, args=(grid,), rounds=3, iterations=1)
    benchmark.extra_info.update(method=method, unknowns=len(grid.points), nnz=int(mat.nnz))
    # the Q1 Laplacian annihilates constants: every row sums to zero (round-off ~1e-16 of the diagonal)
    assert np.abs(mat @ np.ones(mat.shape[0])).max() <= 1e-12 * mat.diagonal().max()
