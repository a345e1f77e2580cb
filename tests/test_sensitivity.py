"""`pcverify sensitivity` on a tiny steady heat study: a perturbed conductivity moves the temperature by -dk/k,
the box's size by (1 + step)^2, the heat capacity and the density of a steady cell are blind spots, a box
extent that no longer fits the lattice is refused, an input of groups no claim reads is unread, and bad input is
one line."""

from __future__ import annotations

import contextlib
import io
import json
import math
import shutil
from pathlib import Path

import pytest

from pcverify.fingerprint import source_closure
from pcverify.harness.cli import main
from pcverify.harness.run.perturbation import Perturbed
from pcverify.harness.run.sensitivity import case_change, moved_parts, not_run, output_change, part_scales

STUDY = """
name = "sens"
title = "a steady slab heated throughout"

[[scene]]
name = "sens-slab"
description = "faces z = 0 and z = L at 0 K, a uniform source: T = s z (L - z) / (2 k)"
box = { width = 0.01, height = 0.01, length = 0.06 }
material = "aluminium"
t_max = 1.0
source = 1e6
held = [{ face = "z0", temperature = 0.0 }, { face = "zL", temperature = 0.0 }]

[[group]]
id = "slab"
title = "steady source"
analysis = "table"
scene = "sens-slab"
solvers = ["skfem"]
n = [3]

[[group]]
id = "extra"
title = "no claim reads this group"
analysis = "table"
scene = "sens-slab"
solvers = ["fipy"]
n = [2]

[[claim]]
id = "slab-mean"
text = "the volume mean is s L^2 / (12 k) = 1.27 K within 0.1"
table = "slab-cells"
metric = "volume_mean"
reference = "analytic"
target = 1.27
tolerance = 0.1
"""


@pytest.fixture(scope="module")
def doc(tmp_path_factory: pytest.TempPathFactory) -> dict:
    folder = tmp_path_factory.mktemp("sens")
    (folder / "sens.toml").write_text(STUDY, encoding="utf-8")
    out = folder / "out"
    args = ["sensitivity", str(folder / "sens.toml"), "--out", str(out), "--json", "--input", "*:material.*",
            "--input", "sens-slab:box*", "--input", "skfem:*", "--input", "fipy:rtol"]
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        assert main(args) == 0
    found = json.loads(buffer.getvalue())
    assert (out / "sens" / "sensitivity-matrix.csv").is_file()
    assert "Which claim sees which input" in (out / "index.html").read_text(encoding="utf-8")
    return found


def entry(doc: dict, name: str) -> dict:
    return next(x for x in doc["inputs"] if x["input"] == name)


def test_conductivity_moves_the_steady_temperature_by_minus_dk_over_k(doc: dict) -> None:
    k = entry(doc, "sens-slab:material.conductivity")
    (case,) = k["claims"]["slab-mean"]
    assert k["factor"] == pytest.approx(1.01) and k["seen_by"] == ["slab-mean"] and case["moved"]
    assert case["relative"] == pytest.approx(1 / 1.01 - 1, rel=1e-6)  # T ~ s / k, exactly so for the linear solve
    assert not case["verdict_changed"]


def test_the_box_size_moves_it_by_the_square_of_the_scale(doc: dict) -> None:
    (case,) = entry(doc, "sens-slab:box")["claims"]["slab-mean"]
    assert case["relative"] == pytest.approx(1.01 ** 2 - 1, rel=1e-6)  # T ~ s L^2 / k


def test_an_input_a_steady_cell_does_not_read_is_a_blind_spot(doc: dict) -> None:
    blind = {b["input"]: b["why"] for b in doc["blind_spots"]}
    for name in ("sens-slab:material.heat_capacity", "sens-slab:material.density"):
        assert blind[name].startswith("inert"), blind
        assert entry(doc, name)["changed_cells"] == 0
    assert "sens-slab:material.conductivity" not in blind and doc["claims_seeing_nothing"] == []


def test_an_input_only_groups_no_claim_reads_have_is_unread(doc: dict) -> None:
    blind = {b["input"]: b for b in doc["blind_spots"]}
    assert blind["fipy:rtol"]["kind"] == "unread" and "extra" in blind["fipy:rtol"]["why"]
    assert entry(doc, "fipy:rtol")["cells"] == 0  # never run


def test_a_value_the_solver_refuses_is_not_perturbed_nor_a_blind_spot(doc: dict) -> None:
    width = entry(doc, "sens-slab:box.width")
    assert width["status"] == "refused" and "cells failed" in width["reason"]
    assert "sens-slab:box.width" in {x["input"] for x in doc["not_perturbed"]}
    assert "sens-slab:box.width" not in {b["input"] for b in doc["blind_spots"]}


def test_a_case_moves_beyond_its_uncertainty_or_a_thousandth_of_its_tolerance_or_its_round_off_bound() -> None:
    base = {"case": "", "value": 1.0, "uncertainty": 0.01, "tolerance": 1.0, "verdict": "pass"}
    assert not case_change(base, base | {"value": 1.005})["moved"]
    assert case_change(base, base | {"value": 1.02})["moved"]
    assert not case_change(base | {"uncertainty": None}, base | {"value": 1.0005, "uncertainty": None})["moved"]
    bound = {"case": "", "value": 0.01, "target": 0.02, "tolerance": 0.0, "verdict": "pass"}  # at most 0.02
    assert not case_change(bound, bound | {"value": 0.010001})["moved"]
    assert case_change(bound, bound | {"value": 0.0101})["moved"]
    zero = {"case": "", "value": 2.9e-14, "target": 0.0, "tolerance": 2.2e-12, "verdict": "pass",
            "tolerance_basis": "derived: round-off: exactly 0 in exact arithmetic; at most 1e4 eps"}
    assert not case_change(zero, zero | {"value": -4.6e-14})["moved"]  # round-off moving within its own bound
    assert case_change(zero, zero | {"value": 3e-12})["moved"]
    assert case_change(zero | {"tolerance_basis": "measured: 2.9e-14 (76x)"}, zero | {"value": -4.6e-14})["moved"]
    lost = case_change(base, {"value": None, "verdict": "inconclusive"})
    assert lost["moved"] and lost["verdict_changed"]


def test_a_refusal_is_a_cell_its_solver_did_not_run_not_a_failed_outcome() -> None:
    """A stability study's runs near a limit fail their energy balance under a 1 % step: those ran (they have
    a cost) and are outcomes the claims judge; a scene the lattice cannot fit, a check that raised or a skip is
    a refusal of the value."""
    assert not_run({"status": "failed", "reason": "SceneError: n=2 does not fit the box"})
    assert not_run({"status": "skipped", "reason": "constraint value 500 K is neither 0 nor t_max"})
    ran = {"status": "failed", "reason": "energy balance off by 0.129", "cost": {"cpu_s": 1.0}, "summary": {}}
    assert not not_run(ran) and not not_run(ran | {"status": "ok"})


CALIBRATED = """
name = "sens-calib"
plugins = ["calib_synthetic"]

[[calibration]]
id = "quad"
solver = "calib-quadratic"
solver_params = { noise = 0.002 }
budget = 12
design_points = 8
seed = 0
replicas = { seed = [1, 2] }
tolerance = 0.05

[[calibration.parameter]]
name = "x"
low = -1.0
high = 1.0

[[calibration.calibrate]]
scene = "bar-heat-faces"
n = 3
metric = "q"
error = "absolute"
reference = { solver = "calib-quadratic", solver_params = { x = 0.3, noise = 0.0 } }

[[calibration.validate]]
scene = "bar-heat-faces"
n = [4]
metric = "q"
error = "absolute"
reference = { solver = "calib-quadratic", solver_params = { x = 0.3, noise = 0.0 } }

[[claim]]
id = "quad-noise-small"
text = "the calibrated objective's replica noise is below 0.01"
table = "quad-summary"
metric = "noise [calibrated on]"
reference = "theory"
target = 0.01
tolerance = 0.0
sense = "at-most"
"""


def test_a_claim_on_a_calibrations_runs_is_out_of_reach_and_strict_says_so(tmp_path: Path) -> None:
    """A calibration makes its own runs, which sensitivity does not perturb: a claim on its tables is listed as
    out of reach, never silently left out, and --strict exits 1 (0 inputs, 0 blind spots is not a pass)."""
    (tmp_path / "calib.toml").write_text(CALIBRATED, encoding="utf-8")
    shutil.copy(Path(__file__).with_name("calib_synthetic.py"), tmp_path)  # a plugin beside its study file
    buffer = io.StringIO()
    with contextlib.redirect_stdout(buffer):
        code = main(["sensitivity", str(tmp_path / "calib.toml"), "--out", str(tmp_path / "out"), "--json",
                     "--strict"])
    found = json.loads(buffer.getvalue())
    assert found["claims_not_reached"] == ["quad-noise-small"] and found["counts"]["inputs"] == 0
    assert code == 1


def test_the_perturbed_cells_cache_key_does_not_hold_the_judging_rules() -> None:
    """A perturbed cell's key holds its task module's fingerprint: that module is not the one that judges what
    moved, so a change of those rules keeps hours of perturbed cells in the cache."""
    closure = source_closure(Perturbed.__module__)
    assert "pcverify.harness.run.perturbation" in closure
    assert "pcverify.harness.run.sensitivity" not in closure, sorted(closure)


@pytest.mark.parametrize("args, words", [
    (["sensitivity", "no-such-study"], "study='no-such-study' is unknown"),
    (["sensitivity", "manufactured", "--step", "0"], "step='0' is not valid; allowed: number in (0, 0.5]"),
    (["sensitivity", "manufactured", "--step", "0.7"], "step='0.7' is not valid"),
    (["sensitivity", "manufactured", "--input", "nothing:*"], "--input 'nothing:*' matches no input of study "
                                                                "manufactured"),
])
def test_bad_input_is_one_line(args: list[str], words: str, capsys: pytest.CaptureFixture[str],
                               tmp_path: Path) -> None:
    assert main([*args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert words in err and err.count("\n") == 1, err


def test_a_small_quantitys_move_is_measured_against_itself_not_a_large_one_beside_it() -> None:
    # the MCA's compressed bar: nu moved 1 % beside E_eff = 7e10 read as a change of 5e-14 (round-off, inert)
    # when every number was held against the result's largest; each part is held against its own magnitude
    field = {"nodes": {"points": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.03]], "values": [0.0, 3e-5]}}
    before = {"status": "ok", "samples": field, "summary": {"E_eff": 7e10, "nu_eff": 0.33, "wall_s": 1.0}}
    after = {**before, "summary": {"E_eff": 7e10, "nu_eff": 0.3333, "wall_s": 9.0}}
    assert output_change(before, after) == {"summary.nu_eff": pytest.approx(0.01, rel=1e-9)}
    moved_field = {"nodes": {"points": field["nodes"]["points"], "values": [1e-20, 3.03e-5]}}
    assert output_change(before, {**before, "samples": moved_field}) == {  # a field against its own largest
        "samples.nodes.values": pytest.approx(0.01, rel=1e-9)}
    assert output_change(before, {**before, "summary": {**before["summary"], "wall_s": 2.0}}) == {}
    assert output_change(before, {**before, "status": "failed"}) == {"status": math.inf}
    assert output_change(before, {**before, "summary": {"E_eff": 7e10}}) == {"summary.nu_eff": math.inf}
    pair_only = {"status": "ok", "summary": {"E_eff": 7e10, "nu_eff": 1e-14}}  # nu = 0 but for round-off
    scales = part_scales([before, pair_only])
    assert scales == {".samples.nodes.points": 0.03, ".samples.nodes.values": 3e-5, ".summary.E_eff": 7e10,
                      ".summary.nu_eff": 0.33}
    noisy = {**pair_only, "summary": {"E_eff": 7e10, "nu_eff": 3e-14}}
    assert output_change(pair_only, noisy) == {"summary.nu_eff": pytest.approx(2.0)}  # alone: a move of 200 %
    assert output_change(pair_only, noisy, scales)["summary.nu_eff"] < 1e-13  # against nu elsewhere: round-off
    noise = {**before, "summary": {"E_eff": 7e10 * (1 + 1e-12), "nu_eff": 0.33}}
    assert moved_parts([output_change(before, after), output_change(before, noise)]) == {
        "summary.nu_eff": pytest.approx(0.01, rel=1e-9)}  # round-off is not a move
    assert moved_parts([{"status": math.inf}]) == {"status": "inf"}  # JSON has no infinity
