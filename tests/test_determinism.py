"""Determinism (issue 6.5): identical inputs and seeds give bit-identical solutions, serial or parallel.

A study with a cell of every time-stepping and continuum solver (the macromolecule lattice with and
without Langevin noise, the MCA, scikit-fem, FiPy, and a stability probe cell) runs once serially
(jobs=1) and once on two worker processes (jobs=2); every cached solution - samples, summary, work
counters, diagnostics, energy histories - must be equal bit for bit (JSON keeps floats as their exact
repr), except wall-clock fields.  A different seed must change the noisy cell, which shows that the
comparison can fail.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.report.reproduce import select_groups
from pcverify.harness.report.write import write_study_report
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute, run_cell
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.scene import Resolution
from pcverify.solvers.registry import SHIPPED

STUDY = """name = "same"
title = "determinism"
[[group]]
id = "paper"
scene = "bar-heat-paper"
solvers = ["macromolecule", "skfem", "fipy"]
n = [2]
solver_params = { macromolecule = { t_end = 2.0, drive_amplitude = 0.05, damping_ratio = 0.01 } }
[[group]]
id = "faces-noise"
scene = "bar-heat-faces"
solvers = ["macromolecule"]
n = [2]
solver_params = { t_end = 1.0 }
sweep = { seed = [3, 4] }
[[group]]
id = "probe"
analysis = "stability"
probe = "map"
scene = "bar-heat-paper"
solvers = ["macromolecule"]
n = [2]
solver_params = { t_end = 1.0, dt_ratio = 0.9 }
"""
MCA_GROUP = """[[group]]
id = "mca"
scene = "bar-heat-faces"
solvers = ["mca"]
n = [2]
"""


def _without_clocks(obj: Any) -> Any:
    """Drop clock fields (names with 'wall' or 'timing', or ending in '_s': seconds) and `cold` (whether the
    worker had solved with that solver before: which worker ran which cell first)."""
    if isinstance(obj, dict):
        return {k: _without_clocks(v) for k, v in obj.items()
                if not ("wall" in k or "timing" in k or k.endswith("_s") or k == "cold")}
    if isinstance(obj, list):
        return [_without_clocks(v) for v in obj]
    return obj


def _entries(folder: Path) -> dict[str, Any]:
    return {p.name: _without_clocks(json.loads(p.read_text())["result"]) for p in folder.glob("*.json")}


@pytest.fixture(scope="module")
def study_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("det") / "same.toml"
    path.write_text(STUDY + (MCA_GROUP if "mca" in SHIPPED else ""))
    return path


def test_serial_and_parallel_are_bit_identical(study_path, tmp_path) -> None:
    study = load_study(str(study_path))
    _, serial = execute(study, Cache(tmp_path / "serial"), jobs=1, progress=False)
    _, parallel = execute(study, Cache(tmp_path / "parallel"), jobs=2, progress=False)
    # every cell ran (a run whose own checks failed, e.g. the map's inaccurate step, counts as failed)
    counts = ("cells", "done", "failed", "cached")
    assert [serial[k] for k in counts] == [parallel[k] for k in counts]
    assert serial["done"] == serial["cells"] >= 7 and serial["statuses"] == parallel["statuses"]
    a, b = _entries(tmp_path / "serial"), _entries(tmp_path / "parallel")
    assert a.keys() == b.keys() and len(a) == serial["cells"]
    for key in a:
        assert a[key] == b[key], f"{a[key]['solver']} differs between serial and parallel"
    statuses = {r["solver"]: r["status"] for r in a.values()}
    assert statuses["skfem"] == statuses["fipy"] == "ok"
    noisy = {r["solver_params"]["seed"]: r for r in a.values() if r["group"] == "faces-noise"}
    # a different seed changes the Langevin run: the comparison above can fail
    assert noisy[3]["samples"]["nodes"]["values"] != noisy[4]["samples"]["nodes"]["values"]


def test_rerun_in_one_process_is_bit_identical(study_path) -> None:
    """The same cell solved twice in one process (numba kernels warm, RNG reseeded) is identical."""
    study = load_study(str(study_path))
    for cell in [c for g in study.groups for c in g.cells if c.solver == "macromolecule"][:3]:
        assert _without_clocks(run_cell(cell)) == _without_clocks(run_cell(cell)), cell.describe()


def test_same_seed_same_arrays_through_the_api() -> None:
    """Through the solver API (no JSON): hotness arrays and energy histories equal with np.array_equal."""
    from pcverify.solvers.particles.macromolecule.solver import Macromolecule

    scene = make_scene("bar-heat-faces")
    a = Macromolecule().solve(scene, Resolution(2), t_end=0.5, seed=11)
    b = Macromolecule().solve(scene, Resolution(2), t_end=0.5, seed=11)
    assert np.array_equal(a.diagnostics["hotness"], b.diagnostics["hotness"])
    assert np.array_equal(a.diagnostics["history"]["rows"], b.diagnostics["history"]["rows"], equal_nan=True)


# seconds measured by a clock: the only columns of a table that may differ between two runs of one study
CLOCK_COLUMNS = ("wall_s", "kernel_s", "kernel_wall_s", "kernel_cpu_s", "assembly_s", "solve_s", "postprocess_s",
                 "calibrated_wall_s", "cpu_s", "cpu_s_unc", "setup_s")
# and what a timed pass records about itself: which worker was cold, how many solves (those under 0.5 s of CPU
# are repeated), the pass's id, machine and start
PASS_COLUMNS = ("cold", "repeats", "run", "machine", "started")
SHIPPED_GROUPS = {  # study: {group: largest n kept} -- a cell of every solver and every analysis, under 2 minutes
    "continuum-heat": {"faces-steady": 4, "patch-convergence": 3},
    "heat-particles": {"paper-all": 3, "paper-replicas": 3, "work-precision-steady": 4},
    "elasticity": {"mca-compression": 3},
    "contact-friction": {"compression": 4},
    "stick-slip": {"cycle": 4},
    "stability": {"limit-mca-heat": 3},
    # every group of the paper's study (runs, damping x drive sweep, Fourier's law, face drives) at its smallest n:
    # before BLAS was pinned its set-up's LAPACK calls ran on 1 or 2 threads with --jobs, differing by 1.5e-8
    "macromolecule": {"paper-runs": 2, "sweep": 2, "fourier-law": 3, "fourier-law-face-drive": 2},
}


def _tables(folder: Path) -> dict[str, str]:
    """Every CSV a study report wrote, with the clock columns removed, as text."""
    out = {}
    for path in sorted(folder.glob("*.csv")):
        if not path.read_text().strip():
            out[path.name] = ""
            continue
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
        kept = [c for c in table.columns if c.split(".")[-1] not in CLOCK_COLUMNS + PASS_COLUMNS]
        out[path.name] = table[kept].to_csv(index=False)
    return out


@pytest.mark.parametrize("name", sorted(SHIPPED_GROUPS))
def test_shipped_tables_are_the_same_on_one_and_two_workers(name, tmp_path) -> None:
    """Groups of every shipped study, at their smallest n, run with --jobs 1 and --jobs 2 from empty caches:
    every table and verdict file they write is byte-identical once the columns a clock measures are dropped
    (wall and kernel seconds: they are measurements of the machine, not of the model)."""
    keep = SHIPPED_GROUPS[name]
    study = select_groups(load_study(name), list(keep))
    groups = [dataclasses.replace(g, cells=[c for c in g.cells if c.n <= keep.get(g.id, 3)]) for g in study.groups]
    study = dataclasses.replace(study, groups=groups, selected=())
    written = []
    for jobs in (1, 2):
        results, _ = execute(study, Cache(tmp_path / f"cache{jobs}"), jobs=jobs, progress=False)
        folder = write_study_report(study, results, tmp_path / f"out{jobs}")
        written.append(_tables(folder))
    assert written[0].keys() == written[1].keys() and len(written[0]) >= 2
    for table in written[0]:
        assert written[0][table] == written[1][table], f"{name}/{table} differs between --jobs 1 and --jobs 2"
