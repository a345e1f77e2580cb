"""Benchmarks of the MCA kernels (tox -e bench; under `--benchmark-disable` each body runs once).

- time stepping: 2000 steps of the bar in tension (n = 6, 576 automata, 1 440 pairs) with the many-body
  term and pair-only, side by side in one benchmark group, so their ratio is measured in one run;
  extra_info carries ns per pair-step;
- fracture: the whole bar-tension-fracture solve at n = 4 (failure, rebuilds);
- heat: the explicit conduction kernel on bar-heat-faces (n = 11, 3 751 automata) to t = 1 s.
"""

from __future__ import annotations

import numpy as np
import pytest

from pcverify.harness.catalogue import make_scene
from pcverify.scene import Box, Resolution
from pcverify.solvers.particles.mca import kernel as mk
from pcverify.solvers.particles.mca.automata import bar_automata
from pcverify.solvers.particles.mca.model import Elastic, Model
from pcverify.solvers.particles.mca.solver import Mca

STEPS = 2000


def _tension_model(many_body: bool) -> Model:
    box = Box()
    aut = bar_automata(box, 6, 2800.0)
    fixm = np.zeros((aut.size, 6), dtype=np.uint8)
    fixv = np.zeros((aut.size, 6))
    zl, z0 = aut.on_face("zL", box.extent), aut.on_face("z0", box.extent)
    fixm[zl, 2] = fixm[z0, 2] = 1
    fixv[zl, 2] = 0.3
    return Model(aut, Elastic(70e9, 0.33, many_body=many_body), fixm=fixm, fixv=fixv)


@pytest.mark.benchmark(group="mca-time-stepping")
@pytest.mark.parametrize("many_body", [True, False])
def test_bench_time_stepping(benchmark, many_body: bool) -> None:
    model = _tension_model(many_body)
    model.advance(model.new_state(), 10)  # compile outside the timing

    def run():
        st = model.new_state()
        before = model.kernel_s
        model.advance(st, STEPS)
        return st, model.kernel_s - before

    st, kernel_s = benchmark.pedantic(run, rounds=3, iterations=1)
    pairs = len(model.aut.pairs)
    benchmark.extra_info.update(many_body=many_body, automata=model.aut.size, pairs=pairs, steps=STEPS,
                                ns_per_pair_step=1e9 * kernel_s / (pairs * STEPS))
    assert int(st.counters[mk.C_STEPS]) == STEPS and int(st.counters[mk.C_STATUS]) == mk.OK


@pytest.mark.benchmark(group="mca-fracture")
def test_bench_fracture_solve(benchmark) -> None:
    solver = Mca()
    scene = make_scene("bar-tension-fracture")
    solver.solve(scene, Resolution(2))  # compile outside the timing
    sol = benchmark.pedantic(solver.solve, args=(scene, Resolution(4)), rounds=3, iterations=1)
    benchmark.extra_info.update(pair_steps=sol.work["pair_steps"], time_steps=sol.work["time_steps"],
                                kernel_s=sol.work["kernel_s"], failure_stress=sol.summary["failure_stress"])
    assert sol.status == "ok"


@pytest.mark.benchmark(group="mca-heat")
def test_bench_heat_explicit(benchmark) -> None:
    solver = Mca()
    scene = make_scene("bar-heat-faces", mode="transient", t_end=1.0)
    solver.solve(scene, Resolution(3))
    sol = benchmark.pedantic(solver.solve, args=(scene, Resolution(11)), rounds=3, iterations=1)
    benchmark.extra_info.update(pair_steps=sol.work["pair_steps"], time_steps=sol.work["time_steps"],
                                ns_per_pair_step=1e9 * sol.work["kernel_s"] / sol.work["pair_steps"])
    assert sol.status == "ok"
