"""Benchmark: the paper's three macromolecule runs (n = 2, 3, 4; f = 50 Hz, D = 0.05a, 15 s).

Timed by pytest-benchmark (tox -e bench); under the default `--benchmark-disable` each runs once.
extra_info carries the work counters and the kernel's nanoseconds per pair-step.
"""

from __future__ import annotations

import pytest

from harness.catalogue import make_scene
from solvers.base import Resolution
from solvers.particles.macromolecule import Macromolecule

SOLVER = Macromolecule()
PAPER = make_scene("bar-heat-paper")


@pytest.mark.parametrize("n", [2, 3, 4])
def test_bench_paper_run(benchmark, n: int) -> None:
    SOLVER.solve(PAPER, Resolution(n), t_end=0.01)  # compile / warm up outside the timing
    sol = benchmark.pedantic(SOLVER.solve, args=(PAPER, Resolution(n)), kwargs={"drive_amplitude": 0.05,
                             "drive_frequency": 50.0, "t_end": 15.0}, rounds=3, iterations=1)
    kernel = sol.diagnostics["kernel_wall_s"]
    benchmark.extra_info.update(
        n=n, particles=sol.summary["particles"], pairs=sol.summary["pairs"], time_steps=sol.work["time_steps"],
        pair_steps=sol.work["pair_steps"], kernel_s=kernel, solve_s=sol.wall_s,
        ns_per_pair_step=1e9 * kernel / sol.work["pair_steps"], status=sol.status,
    )
    assert sol.work["time_steps"] == sol.summary["steps"] > 0
