"""One study on two machines: every number agrees within a stated tolerance and every verdict is in the same state.

The README's determinism promise across machines: bit-identical results on one machine for 1 or 2 workers
(tests/test_determinism.py), and across CPUs and BLAS kernels equal within stated tolerances with every
verdict in the same state.  Another machine is emulated by forcing numpy's and scipy's OpenBLAS kernels
(OPENBLAS_CORETYPE: Haswell against Prescott, the pair that differed most).  The study takes a cell of every
shipped solver (the macromolecule with and without Langevin noise, the MCA's heat, static elasticity and modes,
scikit-fem's heat and modes, FiPy) and three claims, one of which fails.

Tolerances (ten times the largest difference measured between the Haswell, SkylakeX, Sandybridge and Prescott
kernels on this study):
- RTOL, relative to the largest magnitude of the value's array: sample values, summary scalars, energy
  histories, frequencies (measured 1.5e-11, the macromolecule's final kinetic energy after 3000 steps);
- ATOL, absolute, for the numbers that measure round-off or an error against a reference, in their own units
  (T / t_max, a relative residual, a relative energy balance): errors exact to 1e-16 differ by their full size
  between machines (measured 8e-13, the macromolecule's L-infinity error).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

RTOL = 1.5e-10
ATOL = 8e-12
MACHINES = ("Haswell", "Prescott")
# what a clock or the worker measures about itself: not a result
CLOCK_KEYS = ("cold", "repeats", "run", "machine", "started")

STUDY = """name = "machines"
title = "one study on two machines"

[[group]]
id = "paper"
scene = "bar-heat-paper"
solvers = ["macromolecule", "skfem", "fipy"]
n = [2]
solver_params = { macromolecule = { t_end = 2.0, drive_amplitude = 0.05, damping_ratio = 0.01 } }

[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["mca", "macromolecule"]
n = [2]
solver_params = { macromolecule = { t_end = 1.0, seed = 3 } }

[[group]]
id = "modes"
scene = "bar-modes"
solvers = ["mca", "skfem-elastic"]
n = [3]

[[group]]
id = "compression"
scene = "bar-compression"
solvers = ["mca"]
n = [3]

[[claim]]
id = "paper-bulk-continuum"
text = "scikit-fem and FiPy give the same bulk level on the paper's bar at n = 2 (they do not: 0.06 apart)"
table = "paper-cells"
select = { solver = "skfem" }
against = { solver = "fipy" }
metric = "bulk_median"
reference = "same-grid"
tolerance = 0.05

[[claim]]
id = "mca-E"
text = "MCA returns E = 70 GPa on bar-compression"
table = "compression-cells"
metric = "E_eff"
reference = "analytic"
target = 70e9
tolerance = 1e8

[[claim]]
id = "mca-bending"
text = "MCA's lowest bending frequency within 3000 Hz of scikit-fem's at n = 3"
table = "modes-cells"
select = { solver = "mca" }
against = { solver = "skfem-elastic" }
metric = "f_bending_y_hz"
reference = "mesh-dependent"
tolerance = 3000.0
"""


def _is_clock(key: str) -> bool:
    return "wall" in key or "timing" in key or key.endswith("_s") or key in CLOCK_KEYS


def _round_off(path: str) -> bool:
    """Numbers that measure round-off or an error against a reference: compared absolutely."""
    return path.startswith(".errors") or "residual" in path or path.endswith("energy_balance_error")


def leaves(obj: Any, path: str = "") -> Iterator[tuple[str, Any]]:
    """(path, value) of every result leaf but the clocks; numeric lists as float arrays."""
    if isinstance(obj, dict):
        for key, value in obj.items():
            if not _is_clock(key):
                yield from leaves(value, f"{path}.{key}")
    elif isinstance(obj, list):
        try:
            array = np.asarray(obj, dtype=float)
        except (ValueError, TypeError):
            array = None
        if array is not None and array.size:
            yield path, array
        else:
            for i, value in enumerate(obj):
                yield from leaves(value, f"{path}[{i}]")
    elif isinstance(obj, bool | str) or obj is None:
        yield path, obj
    else:
        yield path, np.asarray(float(obj))


def differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    """What differs between two results beyond RTOL / ATOL (texts, flags and shapes exactly)."""
    la, lb = dict(leaves(a)), dict(leaves(b))
    if la.keys() != lb.keys():
        return [f"keys differ: {sorted(set(la) ^ set(lb))}"]
    out = []
    for path, x in la.items():
        y = lb[path]
        if not isinstance(x, np.ndarray) or not isinstance(y, np.ndarray):
            if x != y:
                out.append(f"{path}: {x!r} != {y!r}")
            continue
        if x.shape != y.shape or not np.array_equal(np.isnan(x), np.isnan(y)):
            out.append(f"{path}: shape or NaNs differ")
            continue
        diff = np.nan_to_num(np.abs(x - y))
        if _round_off(path):
            bound = ATOL
        else:
            finite = np.abs(x[np.isfinite(x)])
            bound = RTOL * (finite.max() if finite.size else 0.0)
        if diff.max(initial=0.0) > bound:
            out.append(f"{path}: differs by {diff.max():.3g} > {bound:.3g}")
    return out


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, dict[str, Any]]:
    """The study run on each emulated machine: its verdict records and its cached results by key."""
    folder = tmp_path_factory.mktemp("machines")
    study = folder / "machines.toml"
    study.write_text(STUDY)
    out = {}
    for core in MACHINES:
        cache, report = folder / f"cache-{core}", folder / f"out-{core}"
        done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "study", str(study), "--json",
                               "--cache", str(cache), "--out", str(report)],
                              env=os.environ | {"OPENBLAS_CORETYPE": core}, capture_output=True, text=True,
                              timeout=900)
        assert done.returncode == 0, done.stderr[-2000:]
        summary = json.loads(done.stdout)[0]
        results = {p.name: json.loads(p.read_text())["result"] for p in cache.glob("*.json")}
        out[core] = {"summary": summary, "results": results}
    return out


def test_every_verdict_is_in_the_same_state_with_its_value_within_tolerance(runs) -> None:
    a, b = (runs[core]["summary"]["verdicts"] for core in MACHINES)
    assert [(v["claim"], v["case"]) for v in a] == [(v["claim"], v["case"]) for v in b]
    assert [v["verdict"] for v in a] == [v["verdict"] for v in b]
    assert {v["verdict"] for v in a} == {"pass", "fail"}  # both states are there to be kept
    for x, y in zip(a, b, strict=True):
        assert y["value"] == pytest.approx(x["value"], rel=RTOL), x["claim"]


def test_every_cached_number_agrees_within_its_tolerance(runs) -> None:
    a, b = (runs[core]["results"] for core in MACHINES)
    assert a.keys() == b.keys() and len(a) == 8  # the same cells, keyed alike on both machines
    assert runs[MACHINES[0]]["summary"]["statuses"] == runs[MACHINES[1]]["summary"]["statuses"]
    found = {key: differences(a[key], b[key]) for key in a}
    assert not any(found.values()), {k: v[:5] for k, v in found.items() if v}


def test_the_comparison_sees_a_change_of_one_part_in_a_billion(runs) -> None:
    """A result changed by 1e-9 of one value (far below any defect of a model) is reported."""
    result = next(r for r in runs[MACHINES[0]]["results"].values() if r["solver"] == "macromolecule")
    changed = json.loads(json.dumps(result))
    values = changed["samples"]["nodes"]["values"]
    values[0] = values[0] * (1 + 1e-9) + 1e-9 * max(abs(v) for v in values)
    assert differences(result, changed) and not differences(result, json.loads(json.dumps(result)))
