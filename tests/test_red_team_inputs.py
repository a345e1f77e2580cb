"""Red team, inputs that produced a silently wrong answer: scenes whose held points lie outside the body or
between grid nodes, boxes of no physical size, contact runs whose bodies parted or whose averaging window was
cut, a friction reference that ignored the law's own cap and regularisation, and calibrations that reported a
replica they never ran, validated a number they were fitted to, divided by a zero reference or evaluated
nothing.  Each is refused in one line or ends in a non-ok status whose reason carries the numbers."""

from __future__ import annotations

import dataclasses
import json
import re
import sys
import time
from pathlib import Path

import pytest
from red_team import TALLY, tally

from pcverify.harness.cli import main
from pcverify.harness.run.limits import check_work
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.scene import PatchTemperature, PointTemperature, Resolution, Scene, SceneError
from pcverify.solvers.registry import get_solver

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))  # calib_synthetic, the calibration tests' solver with a known optimum


def _error_line(capsys) -> str:
    """The one `pcverify: error: ...` line of a refused in-process command."""
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pcverify: error: "), lines
    return lines[0]


def _run(capsys, *args: str) -> tuple[int, dict]:
    """`pcverify run ... --json` in this process: (exit code, the result)."""
    code = main(["run", *args, "--json"])
    return code, json.loads(capsys.readouterr().out)


# ---------------------------------------------------------------------------------------------------- scenes

PAPER = make_scene("bar-heat-paper")  # hot corner (0, H, 0), frozen corners (W, 0, 0) and (W, 0, L)


def _held_at(point) -> Scene:
    return dataclasses.replace(PAPER, constraints=(PointTemperature(point, 500.0), *PAPER.constraints[1:]))


@pytest.mark.parametrize("make, words", [
    (lambda: _held_at((0.0, 0.01, 5.0)), "point=(0.0, 0.01, 5.0) m lies outside the body"),  # 5 m off a 3 cm bar
    (lambda: _held_at((0.0, 0.0102, 0.0)), "point=(0.0, 0.0102, 0.0) m lies outside the body"),  # 0.2 mm past yH
    (lambda: _held_at((float("nan"), 0.0, 0.0)), "point=(nan, 0.0, 0.0) m lies outside the body"),
    (lambda: dataclasses.replace(PAPER, constraints=(PatchTemperature((-0.001, 0.01, 0.0), 1e-3, 500.0),)),
     "constraint 1 (PatchTemperature) centre=(-0.001, 0.01, 0.0) m lies outside the body"),
])
def test_a_held_point_or_patch_centre_outside_the_body_is_a_scene_error(make, words) -> None:
    """Before: FiPy held the cell nearest the point and answered ok (bulk 0.114 for 5 m outside)."""
    with pytest.raises(SceneError) as err:
        make()
    assert words in str(err.value) and "allowed: a point in the box [0, 0.01] x [0, 0.01] x [0, 0.03] m" in \
        str(err.value) and "\n" not in str(err.value)
    tally("scenes", "rejected")


def test_a_study_scene_with_a_point_outside_is_refused_before_any_solver_runs(tmp_path, capsys) -> None:
    (tmp_path / "s.toml").write_text(
        'name = "s"\n[[scene]]\nname = "held-far"\nt_max = 500.0\n'
        'held = [ { point = [0.0, 0.01, 5.0], temperature = 500.0 }, { face = "zL", temperature = 0.0 } ]\n'
        '[[group]]\nscene = "held-far"\nsolvers = ["fipy", "skfem"]\nn = [3]\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out")]) == 2
    line = _error_line(capsys)
    assert "constraint 1 (PointTemperature) point=(0.0, 0.01, 5.0) m lies outside the body" in line, line
    assert not (tmp_path / "out").exists()
    tally("scenes", "rejected")


def test_a_point_between_lattice_nodes_is_refused_alike_by_every_solver_that_needs_a_node() -> None:
    """The rule: a held point must be a node of the grid the solver discretises on (h = a / refine; the
    particle solvers' lattice of n).  (0.0025, H, 0) lies between the nodes of n = 3 (a = 5 mm): FiPy, which
    used to hold the cell around it and answer ok, now refuses it with scikit-fem's words; at refine 2 it is a
    node of both grids and both hold it."""
    scene = _held_at((0.0025, 0.01, 0.0))
    words = "point constraint: point (0.0025, 0.01, 0.0) is not a node of the grid with spacing h=0.005 m"
    for name in ("fipy", "skfem", "mca", "macromolecule"):
        with pytest.raises(SceneError) as err:
            get_solver(name).solve(scene, Resolution(3, 1))
        if name in ("fipy", "skfem"):
            assert str(err.value).startswith(words), (name, str(err.value))
        else:  # the particle solvers: no particle at the point
            assert "[0.0025, 0.01, 0.0]" in str(err.value), (name, str(err.value))
    tally("scenes", "rejected")
    fipy, skfem = (get_solver(s).solve(scene, Resolution(3, 2)) for s in ("fipy", "skfem"))
    assert fipy.status == skfem.status == "ok"
    assert fipy.diagnostics["fixed_cells"] == 3  # the hot point's cell and the two frozen corners' cells
    assert abs(fipy.summary["bulk_median"] - skfem.summary["bulk_median"]) < 0.05
    tally("scenes", "accepted")


@pytest.mark.parametrize("scale", [1e-300, 1e-7])
def test_a_box_without_physical_size_is_refused_in_one_line(capsys, scale) -> None:
    """The bar scaled to 1e-300 m (before: failed with a ZeroDivisionError here, an OverflowError traceback at
    n = 2, 'Factor is exactly singular' elsewhere) and to 1e-7 m (before: solved, ok) is refused; at 1e-6 m, the
    smallest box allowed, the steady face scene (scale-free) still solves to round-off."""
    dims = [f"{k}={scale * f!r}" for k, f in (("width", 1), ("height", 1), ("length", 3))]
    assert main(["run", "bar-heat-faces", "--solver", "fipy", "--n", "3", *(a for d in dims for a in ("--set", d))
                 ]) == 2
    line = _error_line(capsys)
    assert f"width={scale!r} is out of range; allowed: number in [1e-06, 1000] m" in line, line
    tally("scenes", "rejected")
    code, out = _run(capsys, "bar-heat-faces", "--solver", "fipy", "--n", "3", "--set", "width=1e-6", "--set",
                     "height=1e-6", "--set", "length=3e-6")
    assert code == 0 and out["status"] == "ok" and out["errors"]["nodes"]["linf"] < 1e-12
    tally("scenes", "accepted")


# --------------------------------------------------------------------------------------------------- contact

def _slide(capsys, scene: str = "block-sliding", *settings: str) -> dict:
    args = [a for s in settings for a in ("--set", s)]
    code, out = _run(capsys, scene, "--solver", "mca", "--n", "4", *args)
    assert code == (1 if out["status"] == "failed" else 0)
    return out


@pytest.mark.parametrize("scene, settings, slid", [
    ("block-sliding", ("speed=100",), "0.105 m along z"),  # 11 cm off a 3 cm base: ended with contacts 0, ok
    ("block-sliding", ("speed=100", "roughness_a1=2", "roughness_a2=1"), "0.105 m along z"),
    ("frictional-heating", ("speed=100",), "0.0348 m along x"),  # the flux was then averaged over a slider in air
])
def test_a_slider_driven_off_its_base_fails_with_the_distance(capsys, scene, settings, slid) -> None:
    out = _slide(capsys, scene, *settings)
    assert out["status"] == "failed", out["reason"]
    assert f"the bodies did not stay in contact: body 2 slid {slid} by the end of the averaging window" in \
        out["reason"]
    assert out["summary"]["slid_distance"] > out["summary"]["slide_room"]
    tally("contact", "rejected")


def test_the_shipped_sliding_energy_claim_fails_on_a_slider_off_its_base(tmp_path, capsys) -> None:
    """Before: the energy balance of the slider in the air closed (3e-5) and the claim passed."""
    (tmp_path / "s.toml").write_text(
        'name = "off"\n[[group]]\nid = "sliding"\nanalysis = "table"\nscene = "block-sliding"\n'
        'scene_params = { speed = 100.0 }\nsolvers = ["mca"]\nn = [4]\n'
        '[[claim]]\nid = "sliding-energy"\ntext = "energy balance"\ntable = "sliding-cells"\nper = "n"\n'
        'metric = "energy_balance_error"\nreference = "theory"\ntarget = 0.0\ntolerance = 1e-3\nsense = "at-most"\n')
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(tmp_path / "out"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)[0]
    assert summary["statuses"] == {"failed": 1}
    assert [v["verdict"] for v in summary["verdicts"]] == ["fail"]
    tally("contact", "rejected")


def test_a_slider_that_bounces_off_its_base_fails_with_the_rows_without_contact(capsys) -> None:
    """Undamped sliding: the friction-induced vibration opens every contact for moments (mu_dr 0.296 was
    averaged over them, ok).  The numbers are kept; the status says the bodies parted, with how many of the
    history rows had no closed contact (a detail of the vibration: it moved with every change of the contact's
    and the pair's laws)."""
    out = _slide(capsys, "block-sliding", "slide_damping=0")
    assert out["status"] == "failed"
    found = re.search(r"the bodies did not stay in contact: no closed contact in (\d+) of 1900 history rows",
                      out["reason"])
    assert found and int(found.group(1)) >= 1  # how many rows open is the vibration's detail (12, 19, 87 so far)
    assert out["summary"]["mu_dr_std"] > 0.05  # the vibration's numbers are kept for the table
    tally("contact", "rejected")


@pytest.mark.parametrize("setting, needs", [("max_steps=4000", "needs 10411 steps"),
                                            ("duration=1", "needs 9498988 steps")])
def test_a_window_that_max_steps_would_cut_fails_before_it_runs(capsys, setting, needs) -> None:
    """Before: max_steps cut the window silently (0.33 ms of 1 ms; 0.53 s of 1 s after 5e6 steps), ok."""
    t0 = time.perf_counter()
    out = _slide(capsys, "block-sliding", setting)
    assert out["status"] == "failed" and "would be reached before the averaging window ends" in out["reason"]
    assert needs in out["reason"] and out["work"]["time_steps"] == 0
    assert time.perf_counter() - t0 < 30
    tally("contact", "rejected")


def test_estimate_counts_the_steps_the_duration_needs() -> None:
    """Before: the estimate counted the preload's relaxation only (9000 steps for a 1 s slide), so the work
    limits let a 1 s slide at n = 20 (2e13 unknown-steps) start."""
    mca = get_solver("mca")
    steps = mca.estimate(make_scene("block-sliding", duration=1.0), Resolution(4)).steps
    assert 9.5e6 < steps < 1.5e7  # 1 s / dt (1.05e-7 s measured; the estimate's dt is 0.25 cfl h / c, smaller)
    with pytest.raises(SceneError, match=r"mca on block-sliding at n=20 refine=1 is 2.\d+e\+05 unknowns x "
                                         r"7.\d+e\+07 time steps"):
        check_work(mca, make_scene("block-sliding", duration=1.0), Resolution(20), {}, allow_large=False)
    tally("contact", "rejected")


@pytest.mark.parametrize("settings, expected, tol", [
    # the normal stress that counts is capped at sigma0: mu1 sigma0 / sigma_N, exact while every contact is above
    # the cap; the friction's moment at the interface tilts the slider ((max - min) / mean pressure 0.93), so the
    # edge contacts fall below 5e5 and the cap bites less: measured 1.06e-3 under
    (("sigma0=5e5",), 0.15, 2e-3),
    (("v_reg=2",), 0.15, 1e-5),  # every contact slides at V = 1 m/s below v_reg: mu1 V / v_reg
])
def test_mu_dr_expected_follows_the_cap_and_the_regularisation_of_the_law(capsys, settings, expected, tol) -> None:
    """Before: the expected value was mu1 = 0.3 whatever sigma0 and v_reg, a false 50 % error."""
    out = _slide(capsys, "block-sliding", *settings)
    assert out["status"] == "ok", out["reason"]
    assert out["summary"]["mu_dr_expected"] == pytest.approx(expected, rel=1e-12)
    assert out["summary"]["mu_dr_error"] < tol
    tally("contact", "accepted")


def test_mu_dr_expected_under_a_platen_uses_the_normal_force_the_contacts_carry(capsys) -> None:
    """Viscous friction under the platen: mu_dr = F_dr / F_N with F_N the contacts' normal force (98 % of the
    applied one), so mu0 V / sigma is taken at that pressure.  Before: mu0 V / sigma_N, a 1.8 % error."""
    out = _slide(capsys, "frictional-heating", "mu1=0", "mu0=3e5")
    assert out["status"] == "ok" and out["summary"]["normal_force_ratio"] < 0.99
    assert out["summary"]["mu_dr_error"] < 1e-3
    tally("contact", "accepted")


def test_a_slider_that_stays_on_its_base_is_ok(capsys) -> None:
    out = _slide(capsys, "block-sliding")
    assert out["status"] == "ok" and out["summary"]["mu_dr_error"] < 1e-5
    assert out["summary"]["slid_distance"] == pytest.approx(1.048e-3, rel=1e-3)  # V (ramp / 2 + duration)
    assert out["summary"]["slide_room"] == pytest.approx(0.01 + 0.5 * 0.01 / 3)  # to the base's end + a / 2
    tally("contact", "accepted")


# ----------------------------------------------------------------------------------------------- calibration

CALIBRATION = """
name = "cal"
plugins = [{plugins}]
{scenes}
[[calibration]]
id = "quad"
solver = "{solver}"
budget = {budget}
design_points = 2
starts = 0
{replicas}

[[calibration.parameter]]
name = "x"
low = -1.0
high = 1.0

[[calibration.calibrate]]
scene = "bar-heat-faces"
n = [3, 4]
metric = "q"
error = "{error}"
reference = {{ solver = "calib-quadratic", solver_params = {{ x = 0.3, y = 0.01, noise = 0.0 }} }}

[[calibration.validate]]
{validate}
metric = "q"
error = "absolute"
reference = {{ solver = "calib-quadratic", solver_params = {{ x = 0.3, y = 0.01, noise = 0.0 }} }}
"""
HELD_OUT = 'scene = "bar-heat-paper"\nn = 3'


def _calibration(tmp_path: Path, solver: str = "calib-quadratic", budget: int = 4, replicas: str = "",
                 error: str = "absolute", validate: str = HELD_OUT, scenes: str = "",
                 plugins: str = '"calib_synthetic"') -> Path:
    path = tmp_path / "cal.toml"
    path.write_text(CALIBRATION.format(solver=solver, budget=budget, replicas=replicas, error=error,
                                       validate=validate, scenes=scenes, plugins=plugins))
    return path


def test_a_replica_that_names_a_free_parameter_is_refused_at_load(tmp_path, capsys) -> None:
    """Before: the optimum overrode it, and the noise table reported the optimum's objective as x = 0.9's."""
    path = _calibration(tmp_path, replicas="replicas = { x = [0.9] }")
    assert main(["study", str(path), "--dry-run"]) == 2
    line = _error_line(capsys)
    assert "calibration[1] (quad): replicas.x names a free parameter" in line and "allowed: a fixed parameter" in line
    tally("calibration", "rejected")


@pytest.mark.parametrize("validate, scenes", [
    # steady: t_end and dt are read by no solver (before: another scene hash, so "held out" and "validated")
    ('scene = "bar-heat-faces"\nscene_params = { t_end = 5.0 }\nn = 3', ""),
    ('scene = "bar-heat-faces"\nscene_params = { dt = 0.5, t_end = 2.0 }\nn = 4', ""),
    # a particle solver ignores refine: the same run
    ('scene = "bar-heat-faces"\nn = 3\nrefine = 2', ""),
    # the same content under another name and recipe, its steady t_end set
    ('scene = "faces-copy"\nn = 4', '[[scene]]\nname = "faces-copy"\nt_max = 500.0\nt_end = 7.0\nheld = [ '
                                    '{ face = "z0", temperature = 500.0 }, { face = "zL", temperature = 0.0 } ]'),
])
def test_a_validation_cell_that_differs_only_in_what_no_solver_reads_is_an_overlap(tmp_path, capsys, validate,
                                                                                    scenes) -> None:
    path = _calibration(tmp_path, validate=validate, scenes=scenes)
    assert main(["study", str(path), "--dry-run"]) == 2
    line = _error_line(capsys)
    assert "calibration and validation cells overlap (" in line and "(the run of calibration cell bar-heat-faces" \
        in line, line
    tally("calibration", "rejected")


def test_refine_is_an_overlap_only_for_a_solver_that_ignores_it(tmp_path) -> None:
    """A continuum solver reads refine (another grid: held out); one that declares `uses_refine = False` does
    not (the same run: refused)."""
    (tmp_path / "calib_grid_plugin.py").write_text(
        "from calib_synthetic import Quadratic\n\n\n"
        "class GridQuadratic(Quadratic):\n    name = 'calib-quadratic-grid'\n    kind = 'continuum'\n\n\n"
        "class FlatQuadratic(Quadratic):\n    name = 'calib-quadratic-flat'\n    kind = 'continuum'\n"
        "    uses_refine = False\n")
    sys.path.insert(0, str(tmp_path))
    try:
        plugins = '"calib_synthetic", "calib_grid_plugin"'
        validate = 'scene = "bar-heat-faces"\nn = 3\nrefine = 2'
        grid = load_study(str(_calibration(tmp_path, solver="calib-quadratic-grid", validate=validate,
                                           plugins=plugins)))
        assert [c.refine for c in grid.calibrations[0].validate] == [2]
        tally("calibration", "accepted")
        with pytest.raises(SceneError, match="calibration and validation cells overlap .*calib-quadratic-flat "
                                             "ignores refine"):
            load_study(str(_calibration(tmp_path, solver="calib-quadratic-flat", validate=validate,
                                        plugins=plugins)))
        tally("calibration", "rejected")
    finally:
        sys.path.remove(str(tmp_path))


def test_a_relative_error_against_a_zero_reference_is_one_line(tmp_path, capsys) -> None:
    """The synthetic reference at its optimum is exactly 0.  Before: ZeroDivisionError, a traceback."""
    path = _calibration(tmp_path, error="relative")
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--json"]) == 2
    line = _error_line(capsys)
    assert "calibration quad: cell bar-heat-faces n=3 q: its reference" in line and "is 0, so a relative " \
        'error is undefined; allowed: error = "absolute" for this cell' in line, line
    tally("calibration", "rejected")


def test_a_budget_below_the_calibration_cells_is_refused_at_load(tmp_path, capsys) -> None:
    """Two calibration cells: one parameter set costs two runs.  Before (budget 1): nothing evaluated, and
    the summary said 'no parameter set ran ok'."""
    path = _calibration(tmp_path, budget=1)
    assert main(["study", str(path), "--dry-run"]) == 2
    line = _error_line(capsys)
    assert "budget=1 is below the 2 calibration cells" in line and "allowed: integer in [2, 100000]" in line, line
    tally("calibration", "rejected")


def test_zz_inputs_tally() -> None:
    expected = {"scenes": 11, "contact": 12, "calibration": 9}
    for family, count in expected.items():
        tried, rejected, accepted = (TALLY[f"{family} {k}"] for k in ("tried", "rejected", "accepted"))
        print(f"\n{family}: tried {tried}, rejected cleanly {rejected}, accepted correctly {accepted}")
        assert tried == rejected + accepted == count, family
