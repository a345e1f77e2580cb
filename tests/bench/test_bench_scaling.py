"""Benchmarks: the one macromolecule kernel (its step with fixes and computes) from N = 160 to ~10^6 particles.

Lattices n = 4, 16, 41, 70 of the family n x n x (3n-2): N = 160, 11 776, 203 401, 1 019 200, every particle
free (no fix), the fixed pair list as the kernel's stencil (16 offset groups; the list of a vibrating lattice
never changes), one thread.  Each case runs the kernel through `simulate` from random displacements of
0.003a rms, damped (delta = 0.02 m omega), at dt = 0.1 / omega (safety 0.05; omega a Gershgorin bound on
the lattice's top frequency), checks only at the start, twice: `steps` and 2 `steps` (about 2e7 and 4e7 pair-steps,
at least 10 and 20 steps).  extra_info: particles, pairs, unknowns, ns_per_pair_step (the marginal cost of a
step: the difference of the two runs' CPU times over the difference of their pair-steps, so the fixed costs
of a run (allocation, the potential energy at start and end) drop out), run_ns_per_pair_step (the whole
longer run over its pair-steps), bytes_per_particle (the kernel's inputs and its slot arrays) and
peak_rss_mb.  `benchmark_rows.rows_from_benchmark_json` turns a saved run into the rows of the
ns-per-pair-step-against-N plot.  n > 16 runs only with timing on (it would add minutes to the suite).

Run: pytest tests/bench/test_bench_scaling.py --benchmark-enable --benchmark-only
"""

from __future__ import annotations

import json
import resource

import numpy as np
import pytest

from bench.benchmark_rows import rows_from_benchmark_json
from bench.free_lattice import DENSITY, MODEL, free_run, omega_bound
from pcverify.scene import Box
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule.lattice import build_lattice
from pcverify.solvers.particles.macromolecule.modal import free_dofs, hessian, top_modes

SIZES = {4: 160, 16: 11_776, 41: 203_401, 70: 1_019_200}


def lattice_pair_count(n: int) -> int:
    """Pairs with rest distance <= 2a on the n x n x (3n-2) lattice, counted from the offsets."""
    nx, ny, nz = n, n, 3 * n - 2
    total = 0
    for i in range(-2, 3):
        for j in range(-2, 3):
            for k in range(-2, 3):
                if 0 < i * i + j * j + k * k <= 4:
                    total += max(nx - abs(i), 0) * max(ny - abs(j), 0) * max(nz - abs(k), 0)
    return total // 2


@pytest.mark.parametrize("n", [4, 16, 41, 70])
def test_bench_kernel_step(benchmark, n: int) -> None:
    if benchmark.disabled and n > 16:
        pytest.skip(f"n={n} ({SIZES[n]} particles) runs only with timing on (--benchmark-enable, tox -e bench): "
                    "it would add minutes to the untimed test suite")
    lat = build_lattice(Box(), n, DENSITY)
    pairs = len(lat.pairs)
    assert lat.size == SIZES[n] and pairs == lattice_pair_count(n)
    w = omega_bound(lat)
    dt, delta = 0.1 / w, 0.02 * lat.mass * w
    rng = np.random.default_rng(n)
    dx = 0.003 * lat.a * rng.standard_normal(lat.positions.shape)
    x0 = lat.positions + dx - dx.mean(axis=0)
    steps = max(10, round(2e7 / pairs))
    free_run(lat, x0, 2, delta, dt)  # compile or load outside the timing
    short, long = free_run(lat, x0, steps, delta, dt), free_run(lat, x0, 2 * steps, delta, dt)
    benchmark.pedantic(free_run, args=(lat, x0, steps, delta, dt), rounds=3, iterations=1)
    slots = 16 * lat.size
    nbytes = lat.positions.nbytes * 6 + pairs * 3 * 8 + slots * (5 * 8 + 2)
    benchmark.extra_info.update(
        n=n, particles=lat.size, pairs=pairs, unknowns=3 * lat.size, steps=[steps, 2 * steps], threads=1,
        ns_per_pair_step=1e9 * (long.cpu_s - short.cpu_s) / (pairs * steps),
        run_ns_per_pair_step=1e9 * long.cpu_s / (pairs * 2 * steps), bytes_per_particle=nbytes / lat.size,
        peak_rss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, timer="process_time")
    for run in (short, long):
        assert run.status_code == codes.DONE and run.counters[codes.K_HOP_EVENTS] == 0
    assert np.abs(long.x - lat.positions).max() < 0.05 * lat.a  # vibrating about the rest lattice


def test_omega_bound_is_an_upper_bound() -> None:
    """The Gershgorin bound is above the free n = 4 lattice's top frequency, and within a factor 3 of it."""
    lat = build_lattice(Box(), 4, DENSITY)
    k = hessian(lat.positions, lat.pairs, MODEL, lat.a)
    w_top = float(top_modes(k, lat.mass, free_dofs(np.ones(lat.size, dtype=bool)), k=1)[0][-1])
    assert w_top <= omega_bound(lat) < 3 * w_top


def test_rows_from_benchmark_json(tmp_path) -> None:
    """The plot's rows: only benchmarks with particles, ns_per_pair_step and bytes_per_particle, sorted by N."""
    doc = {"benchmarks": [
        {"name": "b2", "extra_info": {"particles": 203401, "ns_per_pair_step": 9.0, "bytes_per_particle": 300.0,
                                      "threads": 1}},
        {"name": "b1", "extra_info": {"particles": 160, "ns_per_pair_step": 12.5, "bytes_per_particle": 280.0,
                                      "threads": 1}},
        {"name": "other", "extra_info": {"n": 4}},
    ]}
    path = tmp_path / "bench.json"
    path.write_text(json.dumps(doc))
    rows = rows_from_benchmark_json(path)
    assert [r["N"] for r in rows] == [160, 203401]
    assert rows[0] == {"N": 160, "ns_per_pair_step": 12.5, "bytes_per_particle": 280.0, "threads": 1,
                       "force_pass": "", "name": "b1"}

