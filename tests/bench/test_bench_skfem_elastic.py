"""Benchmark: skfem-elastic linear solvers side by side (the evidence for the `auto` switch points).

Static bar-compression with Q2 at 6 075 and 18 759 unknowns, SuperLU against AMG-CG; modal bar-modes with
Q1 at 2 793 unknowns, one factorisation against ~40 AMG-CG solves inside the shift-invert Lanczos.
Timed by pytest-benchmark (tox -e bench); under the default `--benchmark-disable` each runs once.
extra_info carries unknowns, iterations and the solve time alone (assembly excluded).
"""

from __future__ import annotations

import pytest

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.continuum.skfem_elastic import SkfemElastic

SOLVER = SkfemElastic()
COMPRESSION = make_scene("bar-compression")
MODES = make_scene("bar-modes", modes=6)


@pytest.mark.parametrize("refine", [4, 6])
@pytest.mark.parametrize("linear_solver", ["direct", "amg"])
def test_bench_static_q2(benchmark, refine: int, linear_solver: str) -> None:
    SOLVER.solve(COMPRESSION, Resolution(2, 1), element="q2")  # warm up: imports and the cached element matrix
    sol = benchmark.pedantic(SOLVER.solve, args=(COMPRESSION, Resolution(2, refine)),
                             kwargs={"element": "q2", "linear_solver": linear_solver}, rounds=2, iterations=1)
    benchmark.extra_info.update(unknowns=sol.unknowns, iterations=sol.work["iterations"], solve_s=sol.work["solve_s"],
                                assembly_s=sol.work["assembly_s"], linear_solver=linear_solver)
    assert sol.summary["E_eff"] == pytest.approx(70e9, rel=1e-8)


@pytest.mark.parametrize("linear_solver", ["direct", "amg"])
def test_bench_modal_q1(benchmark, linear_solver: str) -> None:
    SOLVER.solve(MODES, Resolution(2, 1), element="q1")
    sol = benchmark.pedantic(SOLVER.solve, args=(MODES, Resolution(2, 6)),
                             kwargs={"element": "q1", "linear_solver": linear_solver}, rounds=2, iterations=1)
    benchmark.extra_info.update(unknowns=sol.unknowns, iterations=sol.work["iterations"], solves=sol.work["solves"],
                                solve_s=sol.work["solve_s"], linear_solver=linear_solver)
    assert sol.summary["f_bending_x_hz"] == pytest.approx(8534.1015, rel=1e-6)  # Q1, h = 1.67 mm (measured)
