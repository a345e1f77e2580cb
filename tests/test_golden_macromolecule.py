"""Golden files of the macromolecule integrator (LAMMPS style: every variant held to one file).

Each case runs the one kernel a few hundred steps on a small lattice (bar-heat-paper, -patch, -faces at
n = 2, 3; drives shared free-centre and symmetric, Langevin and driven hot faces, absorbing and frozen
far faces, damping on and off, envelope p = 2 and p = 3, a perturbed start, a run with hops, a run
stopped by a check) and compares the final positions and velocities, the energy ledger (start, end,
dissipated, drive and bath work, final kinetic and potential energy, the coarse history), the hotness
sums and the counters with
`tests/golden/macromolecule/<case>.json` BIT FOR BIT: the kernel is deterministic (seeded RNG, fixed
summation order, no fastmath), and JSON stores every float with repr, which round-trips exactly.

The files were written by the fast kernel before the package was refactored to one integrator, so the
refactor is held to the shipped numbers.  Regenerate them only for an intended change of the scheme:

    python tests/test_golden_macromolecule.py --regenerate
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pcverify.harness.spec.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule.setup import prepare
from pcverify.solvers.particles.macromolecule.simulate import run_setup
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

GOLDEN = Path(__file__).parent / "golden" / "macromolecule"
CHECK_EVERY = 10

# name: (scene, scene parameters, n, steps, solver parameters)
CASES: dict[str, tuple[str, dict[str, Any], int, int, dict[str, Any]]] = {
    "paper-n2": ("bar-heat-paper", {}, 2, 400, {}),
    "paper-n2-undamped": ("bar-heat-paper", {}, 2, 400, {"delta": 0.0}),
    "paper-n2-p3": ("bar-heat-paper", {}, 2, 300, {"p": 3.0, "drive_amplitude": 0.02}),
    "paper-n3-symmetric": ("bar-heat-paper", {}, 3, 300, {"drive_sharing": "symmetric", "damping_ratio": 0.05}),
    "paper-n3-perturbed": ("bar-heat-paper", {"placement": "diagonal"}, 3, 300,
                           {"perturbation": 1e-4, "seed": 5, "drive_amplitude": 0.02}),
    "paper-n3-hops": ("bar-heat-paper", {}, 3, 800, {"drive_amplitude": 0.1}),
    "paper-n3-left-bar": ("bar-heat-paper", {}, 3, 1500, {"drive_amplitude": 0.1, "damping_ratio": 0.0}),
    "patch-n3": ("bar-heat-patch", {"rho": 0.004}, 3, 300, {}),
    "faces-n2-langevin": ("bar-heat-faces", {}, 2, 400, {"seed": 3}),
    "faces-n3-langevin-undamped": ("bar-heat-faces", {}, 3, 300, {"seed": 11, "delta": 0.0}),
    "faces-n3-driven": ("bar-heat-faces", {}, 3, 300, {"hot_face": "driven", "far_face": "frozen",
                                                      "face_drive_direction": "z", "seed": 2}),
}


def golden_run(name: str) -> dict[str, Any]:
    """Run case `name` and return what its golden file holds."""
    scene_name, scene_params, n, steps, given = CASES[name]
    scene = make_scene(scene_name, **scene_params)
    p = effective_params(Macromolecule(), given)
    s = prepare(scene, Resolution(n).n, p)
    # the integrator over a fixed window (no stationarity stop: its counter stays -1)
    run = run_setup(s, p | {"t_end": steps * s.dt, "t_start": steps // 3 * s.dt, "stop_tol": 0.0},
                    check_every=CHECK_EVERY)
    assert run.counters[codes.K_STATIONARY] == -1
    energy = dict(zip(("start", "end", "dissipated", "drive_work", "bath_work", "kinetic_end", "potential_end"),
                      run.energy[:7].tolist(), strict=True))
    counters = dict(zip(("steps", "hop_events", "hop_pairs", "first_hop", "status", "stop_step", "hot_steps",
                         "half1", "half2"), run.counters[:codes.K_STATIONARY].tolist(), strict=True))
    return {"case": {"scene": scene_name, "scene_params": scene_params, "n": n, "steps": steps, "params": given},
            "dt": s.dt, "delta": s.delta, "x": run.x.tolist(), "v": run.v.tolist(), "energy": energy,
            "history": run.history.tolist(), "hotness": run.hot.tolist(), "counters": counters,
            "ever": run.ever.tolist()}


def _path(name: str) -> Path:
    return GOLDEN / f"{name}.json"


@pytest.mark.parametrize("name", list(CASES))
def test_run_equals_its_golden_file_bit_for_bit(name: str) -> None:
    """The run's final state, energy ledger, hotness and counters equal the golden file's, every float bit for
    bit (compared as exact float64 values; NaN equal to NaN)."""
    want = json.loads(_path(name).read_text())
    got = json.loads(json.dumps(golden_run(name)))
    assert got["case"] == want["case"] and got["counters"] == want["counters"] and got["ever"] == want["ever"]
    for key in ("dt", "delta", "x", "v", "hotness", "history"):
        a, b = np.asarray(got[key], dtype=float), np.asarray(want[key], dtype=float)
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True), key
    assert got["energy"] == want["energy"]


def test_golden_cases_cover_the_variants() -> None:
    """The files exist, and between them the cases take the Langevin bath, damping on and off, a completed run
    with hop events and a run stopped by a check (a particle left the bar)."""
    runs = {name: json.loads(_path(name).read_text()) for name in CASES}
    assert runs["paper-n3-left-bar"]["counters"]["status"] == codes.LEFT_BAR
    assert {r["counters"]["status"] for k, r in runs.items() if k != "paper-n3-left-bar"} == {codes.DONE}
    assert runs["paper-n3-hops"]["counters"]["hop_events"] > 0
    assert any(r["energy"]["bath_work"] != 0.0 for r in runs.values())
    assert sum(r["delta"] == 0.0 for r in runs.values()) >= 2 and sum(r["delta"] > 0.0 for r in runs.values()) >= 5


def regenerate() -> None:
    """Write every case's golden file (an intended change of the scheme only)."""
    GOLDEN.mkdir(parents=True, exist_ok=True)
    for name in CASES:
        _path(name).write_text(json.dumps(golden_run(name), indent=None, separators=(",", ":")) + "\n")
        print(f"wrote {_path(name)}")


if __name__ == "__main__":
    if sys.argv[1:] != ["--regenerate"]:
        sys.exit("usage: python tests/test_golden_macromolecule.py --regenerate")
    regenerate()
