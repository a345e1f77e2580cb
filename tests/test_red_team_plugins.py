"""Red team, plugins: a hostile or broken solver plugin cannot end, hang, corrupt or mislabel a study.

Plugins that misbehave: whatever a plugin raises, in its import, constructor, `supports`, `estimate`,
parameter check, `solve` or its Solution's serialisation, is one error line (exit 2) or that cell's failed
status with the reason; `sys.exit`, `os._exit` and SIGKILL in one cell of a three-cell study fail that cell
only (the reason names the exit code or signal) and the report is written; a solve that never returns is
killed at `--time-limit`; a plugin's prints never reach the JSON on stdout.

Plugins that change what others see: a solver that changes its scene fails its cell and scikit-fem after
it still sees the study's scene; a `module:Class` whose class calls itself "skfem" is reported under the
name it was asked for.

Every cell runs in a forked worker process, so the cases run in-process through `main` (the crash of a
worker cannot take the test down); the stdout cases run the command line as a subprocess (what reaches file
descriptor 1 of the process itself).
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
import uuid
from pathlib import Path

import pandas as pd
import pytest
from red_team import ENV, check_tally, cli, deadline, popen, processes_with, tally

from pcverify.harness.cli import main
from pcverify.harness.study.catalogue import make_scene
from pcverify.scene import Resolution
from pcverify.solvers.registry import get_solver

MISBEHAVE = "plugins that misbehave"
OTHERS = "plugins that change what others see"

PLUGIN = '''
"""Solvers that behave like scikit-fem except for one thing, at n = 3 (the middle cell of a study)."""
import ctypes
import dataclasses
import os
import signal
import sys
import time

from pcverify import Param, Solution
from pcverify.solvers.protocol import WorkEstimate
from pcverify.solvers.registry import get_solver


def mark(what):
    """Append `what` and the time to the file "marks" beside this module: when a solve began, for the tests."""
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "marks"), "a") as fh:
        fh.write(f"{what} {time.time()!r}\\n")


class Base:
    name = "pv-base"
    kind = "continuum"
    parameters = ()

    def supports(self, scene):
        return True, ""

    def solve(self, scene, resolution, samples=None, **params):
        if resolution.n == 3:
            self.misbehave(scene)
        out = get_solver("skfem").solve(scene, resolution)
        out.solver = self.name
        return out

    def misbehave(self, scene):
        pass


class Raise(Base):
    def misbehave(self, scene):
        raise RuntimeError("plugin exploded")


class Exit0(Base):
    def misbehave(self, scene):
        sys.exit(0)


class Exit3(Base):
    def misbehave(self, scene):
        sys.exit(3)


class Exit7(Base):
    def misbehave(self, scene):
        os._exit(7)


class Kill(Base):
    def misbehave(self, scene):
        os.kill(os.getpid(), signal.SIGKILL)


class Sleep(Base):
    def solve(self, scene, resolution, samples=None, **params):
        mark(resolution.n)
        return super().solve(scene, resolution)

    def misbehave(self, scene):
        time.sleep(10**6)


class Compute(Base):
    """A solve in compiled code that holds the interpreter lock (as a numba kernel does): libc's sleep."""
    def misbehave(self, scene):
        mark("compute")
        ctypes.PyDLL(None).sleep(10**6)


class Printer(Base):
    def supports(self, scene):
        print("supports talks on stdout")
        return True, ""

    def misbehave(self, scene):
        print("solve talks on stdout")
        os.write(1, b"and writes to file descriptor 1\\n")


class Mutator(Base):
    def solve(self, scene, resolution, samples=None, **params):
        face = scene.constraints[0]
        object.__setattr__(face, "value", 0.5 * face.value)  # the hot face at half its temperature
        return super().solve(scene, resolution)


class Impostor(Base):
    name = "skfem"

    def solve(self, scene, resolution, samples=None, **params):
        out = super().solve(scene, resolution)
        if resolution.n == 3:
            out.summary["bulk_median"] = "0.5"  # a number as text: refused at the boundary
        return out


class BadInit(Base):
    def __init__(self):
        raise RuntimeError("constructor exploded")


class BadSupports(Base):
    def supports(self, scene):
        raise RuntimeError("supports exploded")


class BadEstimate(Base):
    def estimate(self, scene, resolution, **params):
        if resolution.n == 3:
            raise RuntimeError("estimate exploded")
        return WorkEstimate(10)


class ExplodingParam(Param):
    def check(self, value):
        raise RuntimeError("parameter check exploded")


class BadParam(Base):
    parameters = (ExplodingParam("boom", 1.0, "", "a parameter whose check raises", low=0.0, high=10.0),)

    def solve(self, scene, resolution, samples=None, boom=1.0, **params):
        return super().solve(scene, resolution)


class Unsendable(Solution):
    def to_dict(self):
        raise SystemExit(5)


class BadSerial(Base):
    def solve(self, scene, resolution, samples=None, **params):
        out = super().solve(scene, resolution)
        if resolution.n != 3:
            return out
        return Unsendable(**{f.name: getattr(out, f.name) for f in dataclasses.fields(out)})
'''


@pytest.fixture(scope="module")
def plugins(tmp_path_factory) -> Path:
    """A folder on sys.path with the hostile solver module `pv_hostile` and modules that fail to import."""
    folder = tmp_path_factory.mktemp("plugins")
    (folder / "pv_hostile.py").write_text(PLUGIN)
    (folder / "pv_import_raises.py").write_text("raise RuntimeError('import exploded')\n")
    (folder / "pv_import_exits.py").write_text("import sys\nsys.exit(4)\n")
    sys.path.insert(0, str(folder))
    yield folder
    sys.path.remove(str(folder))


def _study(folder: Path, *solvers: str, n: tuple[int, ...] = (2, 3, 4), extra: str = "") -> Path:
    """A study file of one group on bar-heat-faces: `solvers` x `n` (default three cells: n = 2, 3, 4)."""
    path = folder / f"pv-{'-'.join(s.split(':')[-1].lower() for s in solvers)}-{len(n)}.toml"
    path.write_text(f'name = "pv"\n[[group]]\nid = "g"\nscene = "bar-heat-faces"\nsolvers = {json.dumps(solvers)}\n'
                    f"n = {list(n)}\n{extra}")
    return path


def _cells(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "pv" / "cells.csv", keep_default_na=False).set_index(["solver", "n"])


def _no_traceback(err: str) -> None:
    assert "Traceback" not in err, err[-2000:]


def _one_line(code: int, err: str) -> str:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("pcverify: error: "), (code, err[-2000:])
    return lines[0]


def _marks(plugins: Path) -> dict[str, float]:
    """What the plugin's solves marked (`mark`): when each began (the time), by what they wrote (n, "compute")."""
    path = plugins / "marks"
    lines = path.read_text().splitlines() if path.exists() else []
    return {k: float(v) for k, v in (line.split() for line in lines)}


def _run_json(capsys, *args: str) -> tuple[int, dict]:
    code = main(["run", "bar-heat-faces", "--n", "3", "--json", *args])
    out, err = capsys.readouterr()
    _no_traceback(err)
    return code, json.loads(out)


# ----------------------------------------------------------------------------- raised anywhere
@pytest.mark.parametrize("module, word", [("pv_import_raises", "RuntimeError: import exploded"),
                                          ("pv_import_exits", "SystemExit: 4")])
def test_a_plugin_that_fails_to_import_is_one_line(plugins, module, word, capsys) -> None:
    """`run --solver mod:Class` and a study naming it: exit 2, one line naming the module and what it raised (a
    module that calls sys.exit on import ended `run` with that exit code and no message)."""
    line = _one_line(main(["run", "bar-heat-faces", "--solver", f"{module}:Solver", "--json"]),
                     capsys.readouterr().err)
    assert module in line and word in line
    line = _one_line(main(["study", str(_study(plugins, f"{module}:Solver")), "--out", str(plugins / "o-imp")]),
                     capsys.readouterr().err)
    assert module in line and word in line
    tally(MISBEHAVE, "rejected")


def test_a_constructor_that_raises_is_one_line(plugins, capsys) -> None:
    """BadInit() raises: `run` and a study that names it are one line naming the class and the error, exit 2."""
    for argv in (["run", "bar-heat-faces", "--solver", "pv_hostile:BadInit"],
                 ["study", str(_study(plugins, "pv_hostile:BadInit")), "--out", str(plugins / "o-init")]):
        line = _one_line(main(argv), capsys.readouterr().err)
        assert "pv_hostile:BadInit" in line and "BadInit() raised RuntimeError: constructor exploded" in line
    tally(MISBEHAVE, "rejected")


def test_supports_that_raises_fails_its_cells(plugins, tmp_path, capsys) -> None:
    """`supports` raises: `run` is a failed cell (exit 1), a study's cells are failed with the reason and its
    report is written (the study file's check and the plan called supports unguarded: a traceback)."""
    code, out = _run_json(capsys, "--solver", "pv_hostile:BadSupports")
    assert code == 1 and out["status"] == "failed"
    assert out["reason"] == "solver 'pv_hostile:BadSupports': supports(scene) raised RuntimeError: supports exploded"
    assert main(["study", str(_study(plugins, "pv_hostile:BadSupports")), "--out", str(tmp_path), "--json"]) == 0
    _no_traceback(capsys.readouterr().err)
    cells = _cells(tmp_path)
    assert list(cells["status"]) == ["failed"] * 3 and cells["reason"].str.contains("supports exploded").all()
    tally(MISBEHAVE, "rejected")


def test_estimate_that_raises_fails_its_cell(plugins, tmp_path, capsys) -> None:
    """`estimate` raises at n=3: `run` is one line (exit 2); in a study that cell is failed unsolved, the two
    others are ok and the report is written."""
    line = _one_line(main(["run", "bar-heat-faces", "--n", "3", "--solver", "pv_hostile:BadEstimate"]),
                     capsys.readouterr().err)
    assert "solver 'pv_hostile:BadEstimate': estimate(scene, resolution) raised RuntimeError: estimate exploded" in line
    assert main(["study", str(_study(plugins, "pv_hostile:BadEstimate")), "--out", str(tmp_path), "--json"]) == 0
    _no_traceback(capsys.readouterr().err)
    cells = _cells(tmp_path).loc["pv_hostile:BadEstimate"]
    assert list(cells["status"]) == ["ok", "failed", "ok"] and "estimate exploded" in cells.loc[3, "reason"]
    tally(MISBEHAVE, "rejected")


def test_a_parameter_check_that_raises_fails_its_cells(plugins, tmp_path, capsys) -> None:
    """A plugin's Param whose check raises (given a value): `run --set` is one line (exit 2), a study's cell is
    failed with the reason and its report written (both were tracebacks)."""
    line = _one_line(main(["run", "bar-heat-faces", "--solver", "pv_hostile:BadParam", "--set", "boom=2"]),
                     capsys.readouterr().err)
    assert "solver 'pv_hostile:BadParam' raised RuntimeError: parameter check exploded" in line
    path = _study(plugins, "pv_hostile:BadParam", n=(2,), extra="solver_params = { boom = 2.0 }\n")
    assert main(["study", str(path), "--out", str(tmp_path), "--json"]) == 0
    _no_traceback(capsys.readouterr().err)
    cells = _cells(tmp_path)
    assert cells["status"].item() == "failed" and "parameter check exploded" in cells["reason"].item()
    tally(MISBEHAVE, "rejected")


@pytest.mark.parametrize("solver, reason", [
    ("Raise", "RuntimeError: plugin exploded"),
    ("BadSerial", "SystemExit: 5"),  # the Solution's to_dict raises SystemExit
])
def test_solve_or_serialisation_that_raises_fails_the_cell(plugins, solver, reason, capsys) -> None:
    code, out = _run_json(capsys, "--solver", f"pv_hostile:{solver}")
    assert code == 1 and out["status"] == "failed" and out["reason"] == reason
    tally(MISBEHAVE, "rejected")


# ----------------------------------------------------------------------------- exits, signals, hangs
@pytest.mark.parametrize("solver, jobs, reason", [
    ("Exit0", 1, "SystemExit: 0"),
    ("Exit3", 1, "SystemExit: 3"),
    ("Exit7", 1, "its worker process ended without a result (exit code 7)"),
    ("Kill", 1, "its worker process ended without a result (killed by signal 9, SIGKILL)"),
    ("Exit7", 2, "its worker process ended without a result (exit code 7)"),
    ("Kill", 2, "its worker process ended without a result (killed by signal 9, SIGKILL)"),
])
def test_an_exit_or_a_kill_fails_one_cell_of_three(plugins, tmp_path, solver, jobs, reason, capsys) -> None:
    """sys.exit(0) ended the study with exit 0 and no report, sys.exit(3) stopped it, os._exit and SIGKILL in a
    worker were tracebacks: now exactly the n=3 cell is failed with the exit code or signal (with --jobs 2 after
    a rerun alone), the two others are ok, the report is written and the study exits 0."""
    path = _study(plugins, f"pv_hostile:{solver}")
    assert main(["study", str(path), "--out", str(tmp_path), "--json", "--jobs", str(jobs)]) == 0
    out, err = capsys.readouterr()
    _no_traceback(err)
    summary = json.loads(out)[0]
    assert summary["done"] == 3 and summary["failed"] == 1 and summary["statuses"] == {"failed": 1, "ok": 2}
    cells = _cells(tmp_path).loc[f"pv_hostile:{solver}"]
    assert list(cells["status"]) == ["ok", "failed", "ok"] and cells.loc[3, "reason"] == reason
    assert (tmp_path / "index.html").exists() and (tmp_path / "pv" / "manifest.json").exists()
    tally(MISBEHAVE, "rejected")


def test_a_solve_that_never_returns_is_killed_at_the_time_limit(plugins, tmp_path, capsys) -> None:
    """A solve sleeping forever hung `run` and the study: with --time-limit 5 `run` ends ~5 s after the solve
    began, with the cell failed (exit 1), and the study's other cells are ok and its report written.  Times are
    taken from the moment the solve began (its own mark), not from the command's start: setting up and starting
    a worker takes what a busy machine gives it; the kill itself must come at the limit, not seconds later.
    The other cells share the short limit, so scikit-fem is imported and set up here first: the workers forked
    from this process inherit it, and their cells take milliseconds, not a cold start that on a loaded machine
    passed the 5 s."""
    get_solver("skfem").solve(make_scene("bar-heat-faces"), Resolution(2))
    (plugins / "marks").unlink(missing_ok=True)
    t0 = time.monotonic()
    with deadline(120):  # a limit not applied would hang the suite for 10**6 s
        code, out = _run_json(capsys, "--solver", "pv_hostile:Sleep", "--time-limit", "5")
    ended = time.time()
    assert code == 1 and out["reason"] == "exceeded the time limit of 5 s (its worker process was killed)"
    assert time.monotonic() - t0 >= 5  # not before its limit
    assert ended - _marks(plugins)["3"] < 5 + 5  # the limit after the solve began, the kill, the result printed
    (plugins / "marks").unlink()
    t0 = time.monotonic()
    path = _study(plugins, "pv_hostile:Sleep")
    with deadline(300):
        assert main(["study", str(path), "--out", str(tmp_path), "--json", "--time-limit", "5"]) == 0
    assert time.monotonic() - t0 >= 5
    began = _marks(plugins)
    assert list(began) == ["2", "3", "4"] and began["4"] - began["3"] < 5 + 5  # the next cell, once n = 3 is killed
    _no_traceback(capsys.readouterr().err)
    cells = _cells(tmp_path).loc["pv_hostile:Sleep"]
    assert list(cells["status"]) == ["ok", "failed", "ok"] and "time limit of 5 s" in cells.loc[3, "reason"]
    tally(MISBEHAVE, "rejected")


def test_a_study_killed_during_a_solve_leaves_no_worker_computing(plugins, tmp_path) -> None:
    """The study's process SIGKILLed (as the OOM killer would) while a worker is in a compiled solve that holds
    the interpreter lock (no watchdog thread of the worker can run): the worker was left computing, orphaned,
    until its solve ended (for ever here); now it dies with the study."""
    (plugins / "marks").unlink(missing_ok=True)
    marker = uuid.uuid4().hex
    env = {**ENV, "PYTHONPATH": str(plugins), "PCVERIFY_RED_TEAM_MARK": marker}
    proc = popen("run", "bar-heat-faces", "--solver", "pv_hostile:Compute", "--n", "3", cwd=tmp_path,
                 env=env)
    end = time.monotonic() + 120
    while len(processes_with(marker)) < 2 and time.monotonic() < end:  # the study and its worker
        time.sleep(0.1)
    assert len(processes_with(marker)) >= 2, "no worker started"
    while "compute" not in _marks(plugins):  # the worker is in the solve
        assert proc.poll() is None and time.monotonic() < end, "the solve did not begin"
        time.sleep(0.05)
    os.kill(proc.pid, signal.SIGKILL)
    proc.communicate(timeout=60)
    end = time.monotonic() + 30  # the kernel kills it at once; a busy machine may take a while to reap it
    while processes_with(marker) and time.monotonic() < end:
        time.sleep(0.1)
    assert not processes_with(marker), "a worker of the killed study is still running"
    tally(MISBEHAVE, "accepted")


def test_a_bad_time_limit_is_one_line(capsys) -> None:
    line = _one_line(main(["run", "bar-heat-faces", "--solver", "skfem", "--time-limit", "0"]), capsys.readouterr().err)
    assert "time-limit='0' is not valid; allowed: seconds in (0, " in line
    tally(MISBEHAVE, "rejected")


# ----------------------------------------------------------------------------- stdout
@pytest.mark.parametrize("command", ["run", "study"])
def test_a_plugin_that_prints_leaves_the_json_alone(plugins, tmp_path, command) -> None:
    """A plugin printing in `supports` (in the study's process) and in `solve` (print and a write to file
    descriptor 1, in the worker): `run --json` and `study --json` stdout is exactly the JSON, the prints are on
    stderr."""
    if command == "run":
        args = ["run", "bar-heat-faces", "--n", "3", "--solver", "pv_hostile:Printer", "--json"]
    else:
        args = ["study", str(_study(plugins, "pv_hostile:Printer")), "--out", str(tmp_path), "--json"]
    env = {**ENV, "PYTHONPATH": os.pathsep.join(p for p in (str(plugins), ENV.get("PYTHONPATH")) if p)}
    done = cli(*args, cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr[-2000:]
    parsed = json.loads(done.stdout)
    assert (parsed["status"] == "ok") if command == "run" else (parsed[0]["statuses"] == {"ok": 3})
    for text in ("supports talks on stdout", "solve talks on stdout", "and writes to file descriptor 1"):
        assert text in done.stderr and text not in done.stdout
    tally(MISBEHAVE, "rejected")


# ----------------------------------------------------------------------------- what others see
def test_a_solver_that_changes_its_scene_fails_and_skfem_still_sees_the_study_scene(plugins, tmp_path,
                                                                                    capsys) -> None:
    """Mutator halves the hot face's temperature of the scene it is given (object.__setattr__ on the frozen
    constraint) before scikit-fem's cell of the same group: scikit-fem gave bulk 0.25 instead of 0.5, stored
    under the unchanged scene's key.  Now the mutating cell is failed and scikit-fem's bulk is 0.5, also when
    read back from the cache."""
    path = _study(plugins, "pv_hostile:Mutator", "skfem", n=(2,))
    for _ in range(2):  # computed, then from the cache
        assert main(["study", str(path), "--out", str(tmp_path), "--json"]) == 0
        _no_traceback(capsys.readouterr().err)
        cells = _cells(tmp_path)
        skfem, mutator = cells.loc[("skfem", 2)], cells.loc[("pv_hostile:Mutator", 2)]
        assert skfem["status"] == "ok" and float(skfem["bulk_median"]) == pytest.approx(0.5)
        assert mutator["status"] == "failed"
        assert "solver 'pv_hostile:Mutator' modified the scene it was given" in mutator["reason"]
    tally(OTHERS, "rejected")


def test_a_solver_calling_itself_skfem_is_reported_under_its_own_name(plugins, tmp_path, capsys) -> None:
    """Impostor (name = "skfem", its Solution says solver="skfem"): `run --json` said solver "skfem"; now it
    is "pv_hostile:Impostor", in the text output too; a study's tables have no skfem row, and the boundary's
    refusal of its n=3 output names pv_hostile:Impostor, not skfem."""
    assert main(["run", "bar-heat-faces", "--n", "2", "--solver", "pv_hostile:Impostor", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["solver"] == "pv_hostile:Impostor"
    assert main(["run", "bar-heat-faces", "--n", "2", "--solver", "pv_hostile:Impostor"]) == 0
    assert "solver   pv_hostile:Impostor " in capsys.readouterr().out
    assert main(["study", str(_study(plugins, "pv_hostile:Impostor")), "--out", str(tmp_path), "--json"]) == 0
    capsys.readouterr()
    for table in (tmp_path / "pv").glob("*.csv"):
        assert set(pd.read_csv(table)["solver"]) == {"pv_hostile:Impostor"}, table.name
    reason = _cells(tmp_path).loc[("pv_hostile:Impostor", 3), "reason"]
    assert reason.startswith("solver 'pv_hostile:Impostor' returned summary['bulk_median'] = '0.5'"), reason
    assert "skfem" not in reason
    tally(OTHERS, "rejected")


def test_zz_plugins_tally() -> None:
    check_tally({MISBEHAVE: 19, OTHERS: 2})
