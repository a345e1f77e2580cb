"""Golden files of the macromolecule integrator (LAMMPS's force-style tests: one YAML per case, each value
compared with an epsilon).

Each case runs the one kernel a few hundred steps on a small lattice (bar-heat-paper, -patch, -faces at
n = 2, 3; drives shared free-centre and symmetric, Langevin and driven hot faces, absorbing and frozen
far faces, damping on and off, envelope p = 2 and p = 3, a perturbed start, a run with hops, a run
stopped by a check) and compares with `tests/golden/macromolecule/<case>.yaml`:

- `init`: the set-up's numbers (time step, pair damping delta, force scale A, the damping ratio and the
  stability limit), which come from dense eigensolves;
- `run`: the final positions and velocities, the hotness sums, the coarse energy history and the energy
  ledger, each within its relative epsilon; the counters (steps, hop events, first hop, status, ...) and
  the set of pairs that ever hopped exactly.

Why epsilons: numpy's and scipy's OpenBLAS choose their kernels by CPU (the environment variable
OPENBLAS_CORETYPE forces one), and numba compiles for the host CPU (NUMBA_CPU_NAME=generic does not), so the
last bits of the set-up's eigensolves differ between machines and are carried through the steps.  Each
file's epsilons are derived when it is written (`--regenerate`): ten times the larger of
  (a) the spread of the value over the emulated machines: OPENBLAS_CORETYPE Haswell, SkylakeX, Sandybridge
      and Prescott with numba for the host, and generic numba with the default and the Prescott kernels;
  (b) its response to the set-up's round-off carried through the run: the same case with the force scale A
      and the pair damping delta changed by a relative SETUP_ROUND_OFF (above the largest spread of any
      set-up number over those machines, 9.8e-13), in two sign patterns.
The error of an array is max |got - want| over the largest |want| of its quantity (a column of x, v and
the history, a row of the hotness sums); of the ledger, over its largest entry.  No epsilon may exceed
MAX_EPSILON, so a regenerated file cannot drift to a comparison that sees nothing.

The chaotic cases (hops, the perturbed start, the run that leaves the bar) are compared over a horizon
short enough that round-off has not grown past 1e-7 of any value (set-up round-off of 1e-12 grows to 9e-8
of the velocities in the 1500 steps of the run that leaves the bar, to 8e-10 in the 800 of the hops); their
counters (hop events, the step a particle left the bar) were equal on every emulated machine and under both
set-up perturbations, so they are compared exactly.  A case whose counters differ between those runs is
refused at regeneration.

Regenerate only for an intended change of the scheme (it runs every case on the emulated machines):

    python tests/test_golden_macromolecule.py --regenerate
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule.setup import Setup, prepare
from pcverify.solvers.particles.macromolecule.simulate import run_setup
from pcverify.solvers.particles.macromolecule.solver import Macromolecule
from pcverify.solvers.protocol import effective_params

GOLDEN = Path(__file__).parent / "golden" / "macromolecule"
CHECK_EVERY = 10
FACTOR = 10.0  # epsilon = FACTOR x the larger of the spread over machines and the response to set-up round-off
SETUP_ROUND_OFF = 1e-12  # relative change of A and delta for the response (b)
PERTURBATIONS = ((1.0, 1.0), (1.0, -1.0))  # signs of (A, delta)
MAX_EPSILON = 1e-6  # a larger epsilon hides real defects: the case's horizon is too long
FLOOR = 1e-15  # the least epsilon: a value equal everywhere is still compared to a few ulp
# the emulated machines: environment over the test's own
MACHINES = {
    "openblas-Haswell": {"OPENBLAS_CORETYPE": "Haswell"},
    "openblas-SkylakeX": {"OPENBLAS_CORETYPE": "SkylakeX"},
    "openblas-Sandybridge": {"OPENBLAS_CORETYPE": "Sandybridge"},
    "openblas-Prescott": {"OPENBLAS_CORETYPE": "Prescott"},
    "numba-generic": {"NUMBA_CPU_NAME": "generic"},
    "numba-generic-Prescott": {"NUMBA_CPU_NAME": "generic", "OPENBLAS_CORETYPE": "Prescott"},
}

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
INIT_KEYS = ("dt", "delta", "stiffness_A", "damping_ratio", "dt_limit")
ENERGY_KEYS = ("start", "end", "dissipated", "drive_work", "bath_work", "kinetic_end", "potential_end")
COUNTER_KEYS = ("steps", "hop_events", "hop_pairs", "first_hop", "status", "stop_step", "hot_steps", "half1",
                "half2")
# the axis along which an array's entries are one quantity (its scale is taken over that axis)
ARRAY_AXIS = {"x": 0, "v": 0, "history": 0, "hotness": 1}


def golden_run(name: str, perturb: tuple[float, float] = (0.0, 0.0)) -> dict[str, Any]:
    """Run case `name` (A and delta changed by the relative amounts `perturb`) and return its values."""
    scene_name, scene_params, n, steps, given = CASES[name]
    p = effective_params(Macromolecule(), given)
    s = prepare(make_scene(scene_name, **scene_params), Resolution(n).n, p)
    s = _perturbed(s, *perturb)
    # the integrator over a fixed window (no stationarity stop: its counter stays -1)
    run = run_setup(s, p | {"t_end": steps * s.dt, "t_start": steps // 3 * s.dt, "stop_tol": 0.0},
                    check_every=CHECK_EVERY)
    assert run.counters[codes.K_STATIONARY] == -1
    return {
        "init": {"dt": s.dt, "delta": s.delta, "stiffness_A": s.stiffness_A, "damping_ratio": s.damping_ratio,
                 "dt_limit": s.dt_limit},
        "run": {"x": run.x.tolist(), "v": run.v.tolist(), "hotness": run.hot.tolist(),
                "history": run.history.tolist(),
                "energy": dict(zip(ENERGY_KEYS, run.energy[:7].tolist(), strict=True)),
                "counters": dict(zip(COUNTER_KEYS, run.counters[:codes.K_STATIONARY].tolist(), strict=True)),
                "ever": run.ever.astype(int).tolist()},
    }


def _perturbed(s: Setup, d_a: float, d_delta: float) -> Setup:
    if d_a == 0.0 and d_delta == 0.0:
        return s
    a = s.stiffness_A * (1.0 + d_a)
    return dataclasses.replace(s, model=dataclasses.replace(s.model, A=a), stiffness_A=a,
                               delta=s.delta * (1.0 + d_delta))


def errors(got: dict[str, Any], want: dict[str, Any]) -> dict[str, float]:
    """Relative error of every compared float value of `got` against `want` (keys 'init.dt', 'run.x', ...)."""
    out = {f"init.{k}": _relative(got["init"][k], want["init"][k]) for k in INIT_KEYS}
    for key, axis in ARRAY_AXIS.items():
        out[f"run.{key}"] = _relative(got["run"][key], want["run"][key], axis)
    g, w = (np.array([r["run"]["energy"][k] for k in ENERGY_KEYS]) for r in (got, want))
    out["run.energy"] = _relative(g, w, None, np.abs(w).max())
    return out


def _relative(got: Any, want: Any, axis: int | None = None, scale: float | None = None) -> float:
    """max |got - want| over the largest |want| of each quantity (along `axis`), or over `scale`."""
    g, w = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    if g.shape != w.shape:
        return np.inf
    if g.size == 0:
        return 0.0
    if scale is None:
        scale = np.abs(w).max(axis=axis, keepdims=axis is not None) if axis is not None else np.abs(w).max()
        whole = np.abs(w).max()
        scale = np.where(scale > 0, scale, whole if whole > 0 else 1.0)
    diff = np.abs(g - w)
    if np.any(np.isnan(g) != np.isnan(w)):
        return np.inf
    return float(np.nanmax(np.where(np.isnan(diff), 0.0, diff / scale)))


def _path(name: str) -> Path:
    return GOLDEN / f"{name}.yaml"


def _read(name: str) -> dict[str, Any]:
    return yaml.safe_load(_path(name).read_text())


@pytest.mark.parametrize("name", list(CASES))
def test_run_equals_its_golden_file_within_its_epsilons(name: str) -> None:
    """Every set-up number and every run value within its epsilon; counters and hopped pairs exactly."""
    want = _read(name)
    got = golden_run(name)
    assert want["case"] == dict(zip(("scene", "scene_params", "n", "steps", "params"), CASES[name], strict=True))
    assert got["run"]["counters"] == want["run"]["counters"]
    assert got["run"]["ever"] == want["run"]["ever"]
    off = {k: (e, want["epsilon"][k]) for k, e in errors(got, want).items() if not e <= want["epsilon"][k]}
    assert not off, f"beyond epsilon (error, epsilon): {off}"


def test_the_comparison_sees_a_defect_of_one_part_in_a_million() -> None:
    """A set-up off by 1e-6 (far below any model defect worth the name) fails the comparison of the run."""
    want = _read("paper-n2")
    got = golden_run("paper-n2", perturb=(1e-6, 0.0))
    assert any(e > want["epsilon"][k] for k, e in errors(got, want).items() if k.startswith("run."))


def test_golden_files_cover_the_variants_and_keep_tight_epsilons() -> None:
    """The files exist with a derived epsilon for every value, none above MAX_EPSILON; between them the cases
    take the Langevin bath, damping on and off, a completed run with hop events and a run stopped by a check
    (a particle left the bar)."""
    runs = {name: _read(name) for name in CASES}
    for name, r in runs.items():
        assert set(r["epsilon"]) == set(errors(r, r)), name
        assert all(FLOOR <= e <= MAX_EPSILON for e in r["epsilon"].values()), (name, r["epsilon"])
        assert r["derivation"]["factor"] == FACTOR and set(r["derivation"]["machines"]) == set(MACHINES)
    counters = {k: r["run"]["counters"] for k, r in runs.items()}
    assert counters["paper-n3-left-bar"]["status"] == codes.LEFT_BAR
    assert {c["status"] for k, c in counters.items() if k != "paper-n3-left-bar"} == {codes.DONE}
    assert counters["paper-n3-hops"]["hop_events"] > 0
    assert any(r["run"]["energy"]["bath_work"] != 0.0 for r in runs.values())
    deltas = [r["init"]["delta"] for r in runs.values()]
    assert sum(d == 0.0 for d in deltas) >= 2 and sum(d > 0.0 for d in deltas) >= 5


# -- regeneration ------------------------------------------------------------------------------------


def _on_machine(env: dict[str, str], cache: Path) -> dict[str, Any]:
    """Every case's values computed in a subprocess under `env` (an emulated machine), numba's compiled code in
    `cache` (its index is keyed by the target CPU, so the generic build is compiled, not read back)."""
    out = cache / "values.json"
    subprocess.run([sys.executable, __file__, "--values", str(out)], check=True,
                   env=os.environ | env | {"NUMBA_CACHE_DIR": str(cache)})
    return json.loads(out.read_text())


def regenerate() -> None:
    """Write every case's golden file with its derived epsilons (an intended change of the scheme only)."""
    GOLDEN.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        machines = {label: _on_machine(env, Path(tmp)) for label, env in MACHINES.items()}
    for name in CASES:
        here = json.loads(json.dumps(golden_run(name)))
        spread = {k: max(errors(m[name], here)[k] for m in machines.values()) for k in errors(here, here)}
        perturbed = [golden_run(name, (sa * SETUP_ROUND_OFF, sd * SETUP_ROUND_OFF)) for sa, sd in PERTURBATIONS]
        response = {k: max(errors(q, here)[k] for q in perturbed) for k in spread}
        for other in [*(m[name] for m in machines.values()), *perturbed]:
            if other["run"]["counters"] != here["run"]["counters"] or other["run"]["ever"] != here["run"]["ever"]:
                raise SystemExit(f"{name}: counters differ between machines or under set-up round-off: "
                                 "shorten the case's horizon")
        epsilon = {k: max(FLOOR, FACTOR * max(spread[k], response[k])) for k in spread}
        doc = {"case": dict(zip(("scene", "scene_params", "n", "steps", "params"), CASES[name], strict=True)),
               "epsilon": epsilon,
               "derivation": {"factor": FACTOR, "machines": list(MACHINES), "setup_round_off": SETUP_ROUND_OFF,
                              "spread": spread, "response": response},
               "init": here["init"], "run": here["run"]}
        text = (f"# golden file of the macromolecule integrator, case {name}: written by\n"
                "#   python tests/test_golden_macromolecule.py --regenerate\n"
                "# epsilon = factor x max(spread over the emulated machines, response to set-up round-off)\n")
        _path(name).write_text(text + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=120))
        print(f"wrote {_path(name)}: largest epsilon {max(epsilon.values()):.2g}")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--values"] and len(sys.argv) == 3:
        Path(sys.argv[2]).write_text(json.dumps({name: golden_run(name) for name in CASES}))
    elif sys.argv[1:] == ["--regenerate"]:
        regenerate()
    else:
        sys.exit("usage: python tests/test_golden_macromolecule.py --regenerate")
