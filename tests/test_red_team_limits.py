"""Red team, unbounded work and names that become paths: before anything starts, a study of a million cells,
a solve of billions of unknowns or a transient of 10^7 steps is refused in one line that states the
estimate and the limit (--allow-large lifts it); study names and group ids that would leave --out are
refused.  Every case runs the command in this process (a refusal needs no process of its own; a hang
fails the case at its deadline)."""

from __future__ import annotations

import time

import pytest
from red_team import check_tally, one_line_error, run, tally

from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.registry import get_solver


def test_a_million_cell_study_is_refused_before_it_is_built(tmp_path, capfd) -> None:
    """1000 n values x 1000 sweep values: refused from the lengths of the lists alone (the old code spent
    82 s and 2.5 GB enumerating the cells)."""
    n = ", ".join(str(k) for k in range(2, 1002))
    dts = ", ".join(f"{0.001 * (k + 1):.3f}" for k in range(1000))
    (tmp_path / "big.toml").write_text(f'name = "big"\n[[group]]\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\n'
                                       f"n = [{n}]\nsweep = {{ cg_rtol = [{dts}] }}\n")
    t0 = time.perf_counter()
    line = one_line_error(run("study", "big.toml", "--dry-run", cwd=tmp_path, capfd=capfd, seconds=30))
    assert "has 1000000 cells; allowed: at most 10000 without --allow-large" in line
    assert time.perf_counter() - t0 < 30
    tally("limits", "rejected")


@pytest.mark.parametrize("args, words", [
    (["run", "bar-heat-faces", "--solver", "skfem", "--n", "1000"], "needs about 6.98e+03 GiB"),
    (["run", "bar-heat-faces", "--solver", "fipy", "--n", "4", "--refine", "300"], "GiB (2.19e+09 unknowns)"),
    (["run", "bar-compression", "--solver", "skfem-elastic", "--n", "4", "--refine", "20"], "GiB (1.59e+07 unknowns)"),
    (["run", "bar-heat-faces", "--solver", "skfem", "--set", "mode=transient", "--set", "t_end=1", "--set", "dt=1e-7"],
     "1e+07 steps is out of range; allowed: at most max_steps=1000000"),
    (["run", "bar-heat-faces", "--solver", "fipy", "--set", "mode=transient", "--set", "t_end=1e4", "--set",
      "dt=1e-7"], "1e+11 time steps = 1.6e+13 unknown-steps; allowed: at most 1e+11 without --allow-large"),
    (["run", "bar-compression", "--solver", "mca", "--n", "200"], "needs about 91.2 GiB (1.44e+08 unknowns)"),
    (["run", "bar-compression", "--solver", "mca", "--n", "40"], "1.13e+06 unknowns x 1.17e+05 time steps"),
    (["run", "bar-heat-faces", "--solver", "skfem", "--n", "21", "--refine", "2", "--set", "mode=transient",
      "--set", "t_end=100", "--set", "dt=0.0001"], "2.03e+05 unknowns x 1e+06 time steps = 2.03e+11 unknown-steps"),
])
def test_a_solve_beyond_the_limits_is_refused_before_it_starts(tmp_path, args, words, capfd) -> None:
    t0 = time.perf_counter()
    line = one_line_error(run(*args, cwd=tmp_path, capfd=capfd, seconds=60))
    assert words in line, line
    assert time.perf_counter() - t0 < 60  # refused, not started
    tally("limits", "rejected")


def test_a_study_cell_beyond_the_limits_stops_the_study_before_anything_runs(tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text('name = "s"\n[[group]]\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\n'
                                     "n = [2, 1000]\n")
    line = one_line_error(run("study", "s.toml", "--out", "out", cwd=tmp_path, capfd=capfd, seconds=60))
    assert "skfem on bar-heat-faces at n=1000 refine=1 needs about" in line
    assert not list((tmp_path / "out" / "cache").glob("*.json")) if (tmp_path / "out" / "cache").exists() else True
    tally("limits", "rejected")


def test_allow_large_lifts_the_cell_count_limit(tmp_path, capfd) -> None:
    n = ", ".join(str(k) for k in range(2, 12))
    sweep = ", ".join(f"{1e-11 * (k + 1):.1e}" for k in range(1100))
    (tmp_path / "wide.toml").write_text(f'name = "wide"\n[[group]]\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\n'
                                        f"n = [{n}]\nsweep = {{ cg_rtol = [{sweep}] }}\n")
    assert "has 11000 cells" in one_line_error(run("study", "wide.toml", "--dry-run", "--json", cwd=tmp_path,
                                                   capfd=capfd))
    out = run("study", "wide.toml", "--dry-run", "--json", "--allow-large", cwd=tmp_path, capfd=capfd, seconds=600)
    assert out.returncode == 0 and out.stdout.count('"state": "to run"') == 11000
    tally("limits", "accepted")


@pytest.mark.parametrize("line", ['name = "../escape"', 'name = "/tmp/abs"', 'name = ""', 'name = "a/b"',
                                  'name = ".hidden"'])
def test_a_study_name_that_is_not_a_file_name_is_refused(tmp_path, line, capfd) -> None:
    (tmp_path / "s.toml").write_text(f'{line}\n[[group]]\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\nn = [2]\n')
    out = run("study", "s.toml", "--out", "out", cwd=tmp_path, capfd=capfd)
    assert "allowed: 1 to 80 letters, digits" in one_line_error(out)
    assert not (tmp_path / "escape").exists() and not (tmp_path / "out").exists()
    tally("names as paths", "rejected")


@pytest.mark.parametrize("gid", ["../g", "/abs", "", "a/b", "..", "g x"])
def test_a_group_id_that_is_not_a_file_name_is_refused(tmp_path, gid, capfd) -> None:
    (tmp_path / "s.toml").write_text(f'name = "s"\n[[group]]\nid = "{gid}"\nscene = "bar-heat-faces"\n'
                                     'solvers = ["skfem"]\nn = [2]\n')
    assert "id=" in one_line_error(run("study", "s.toml", "--out", "out", cwd=tmp_path, capfd=capfd))
    tally("names as paths", "rejected")


def test_the_mca_estimate_is_near_the_steps_a_fracture_run_takes() -> None:
    """The limits act on the estimate, so it must be the run's size: the fracture run at n = 2 takes 3072
    steps, the estimate (loading time over cfl h / (4 c)) says 3439; within 25 % at both cfl values."""
    mca, scene = get_solver("mca"), make_scene("bar-tension-fracture")
    for cfl in (0.25, 0.5):
        steps = mca.solve(scene, Resolution(2), cfl=cfl).work["time_steps"]
        assert abs(mca.estimate(scene, Resolution(2), cfl=cfl).steps / steps - 1.0) < 0.25
    tally("limits", "accepted")


def test_zz_limits_tally() -> None:
    check_tally({"limits": 12, "names as paths": 11})
