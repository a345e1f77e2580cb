"""Red team, damaged caches and hostile report folders, and signals: zero tracebacks, zero hangs, nothing lost.

Caches and report folders:
- a cache folder that is a file (`--cache FILE`, or OUT/cache a file) is one error line, not a study that waits
  forever;
- a week-old cell lock naming a live pid (pid reuse) or another host is stale: taken over with a warning; a
  young lock of a live holder is waited for, saying which lock file, whose (pid, host) and for how long;
- a cache entry, a manifest, a verdicts.json or a saved benchmark run nested 100 000 deep is an invalid file
  (recomputed, or skipped with a warning), never a RecursionError;
- `report` from a cache that lost one of a calibration's cells keeps the calibration's section, says it is not
  rebuilt and fails its claims naming the cell;
- a manifest naming a study file that declares another study (or a shipped study's name) is refused with a
  warning: that file is not loaded (its plugins not imported) and no study's folder is rewritten from it;
- a study name too long or unsafe for a folder (declared, or taken from the file name) is one error line.

Signals (each in its own process group): SIGTERM while a plugin import sleeps, and while `report` rebuilds, is
the one "terminated" line and exit 143; a study started with SIGINT ignored (`cmd &` from sh) still stops on
SIGTERM and leaves no cell lock; a benchmark regression is one line naming the benchmark and by how much, exit 1.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from red_team import COMMAND, ENV, check_tally, cli, deadline, popen, tally

from pcverify.harness.cli import main
from pcverify.harness.run import cache as cache_module
from pcverify.harness.run.execution import execute, identify
from pcverify.harness.run.limits import DEFAULT_TIME_LIMIT
from pcverify.harness.study.study import load_study

TESTS = Path(__file__).resolve().parent
sys.path.insert(0, str(TESTS))  # calib_synthetic: the synthetic solver (and its sleep) as a study plugin
NESTED = "[" * 100_000 + "]" * 100_000
WEEK = 7 * 86400.0

ALPHA = """name = "alpha"
title = "alpha: scikit-fem on the faces scene"
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["skfem"]
n = [2, 3]

[[claim]]
id = "faces-exact"
text = "scikit-fem reproduces the linear profile"
table = "faces-cells"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
"""

CALIBRATION = """name = "calib"
plugins = ["calib_synthetic"]

[[calibration]]
id = "quad"
solver = "calib-quadratic"
solver_params = { y = 0.01, noise = 0.0 }
budget = 6
design_points = 4
starts = 1
seed = 0
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
reference = { solver = "calib-quadratic", solver_params = { x = 0.3, y = 0.01, noise = 0.0 } }

[[calibration.validate]]
scene = "bar-heat-faces"
n = 4
metric = "q"
error = "absolute"
reference = { solver = "calib-quadratic", solver_params = { x = 0.3, y = 0.01, noise = 0.0 } }

[[claim]]
id = "quad-validated"
text = "at the calibrated x, q is within 0.05 of 0 on the held-out cell"
table = "quad-validation"
select = { role = "validated on" }
per = "cell"
metric = "calibrated_error"
reference = "analytic"
target = 0
tolerance = 0.05
sense = "at-most"
"""

# a plugin module that, when PCV_SLOW_IMPORT names a file, writes it and then sleeps in its import
SLOW_PLUGIN = """import os
import time
from pathlib import Path

if os.environ.get("PCV_SLOW_IMPORT"):
    Path(os.environ["PCV_SLOW_IMPORT"]).write_text("importing")
    time.sleep(60)

from calib_synthetic import Quadratic


class Slow(Quadratic):
    name = "slow-quadratic"
"""

# a plugin module that leaves a file behind when imported: proof that a study file was loaded
MARKER_PLUGIN = """from pathlib import Path

Path(__file__).with_suffix(".imported").write_text("imported")

from calib_synthetic import Quadratic


class Marker(Quadratic):
    name = "{name}-solver"
"""


def _run(argv: list[str], capsys) -> tuple[int, str, str]:
    """`pcverify ARGV` in this process: (exit code, stdout, stderr)."""
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("pcverify: warning: ")]


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """alpha run once into out/ (two cached cells, its report), copied by each test."""
    root = tmp_path_factory.mktemp("files-template")
    (root / "alpha.toml").write_text(ALPHA)
    with contextlib.chdir(root):
        assert main(["study", "alpha.toml", "--out", "out"]) == 0
    assert len(list((root / "out" / "cache").glob("*.json"))) == 2
    return root


@pytest.fixture
def work(template, tmp_path, monkeypatch) -> Path:
    shutil.copytree(template, tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _alpha_key(work: Path, n: int) -> str:
    study = load_study(str(work / "alpha.toml"))
    cell = next(c for c in study.groups[0].cells if c.n == n)
    return identify(cell).key


def _write_lock(cache: Path, key: str, pid: int, host: str, since: float) -> Path:
    lock = cache / f"{key}.lock"
    lock.write_text(json.dumps({"pid": pid, "host": host, "since": since}))
    return lock


# ----------------------------------------------------------------------------- caches and report folders
@pytest.mark.parametrize("where", ["--cache FILE", "OUT/cache a file"])
def test_a_cache_folder_that_is_a_file_is_one_error_line(work, capsys, where) -> None:
    """Before: every cell's lock 'belonged to another process' and the study waited forever, saying nothing."""
    (work / "afile").write_text("not a folder\n")
    argv = ["study", "alpha.toml", "--out", "fresh", "--cache", "afile"]
    if where == "OUT/cache a file":
        (work / "fresh").mkdir()
        (work / "fresh" / "cache").write_text("not a folder\n")
        argv = argv[:4]
    with deadline(60):
        code, out, err = _run(argv, capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("pcverify: error: cache folder"), err
    name = "fresh/cache" if where == "OUT/cache a file" else "afile"
    assert f"cache folder {name} cannot be used: it is a file; allowed: a folder" in lines[0]
    assert (work / "afile").read_text() == "not a folder\n"
    tally("caches and report folders", "rejected")


@pytest.mark.parametrize("holder", ["a live pid of this host", "another host"])
def test_a_week_old_lock_is_taken_over_with_a_warning(work, capsys, holder) -> None:
    """A lock a week old naming a live process (the test's parent: pid reuse) or a process on another host is
    stale (older than twice the default cell time limit): the study takes it over, warns naming it, computes the
    cell and leaves no lock.  Before: it waited for that lock forever."""
    key = _alpha_key(work, 2)
    cache = work / "out" / "cache"
    (cache / f"{key}.json").unlink()
    pid, host = (os.getppid(), socket.gethostname()) if holder == "a live pid of this host" else (4242, "elsewhere")
    lock = _write_lock(cache, key, pid, host, time.time() - WEEK)
    with deadline(60):
        code, out, err = _run(["study", "alpha.toml", "--out", "out"], capsys)
    assert code == 0, err[-1500:]
    warned = [w for w in _warnings(err) if str(Path("out") / "cache" / f"{key}.lock") in w]
    assert len(warned) == 1 and f"pid {pid} on host {host}" in warned[0] and "7.0 days old" in warned[0], err
    assert "stale, taken over" in warned[0] and "(twice the cell time limit)" in warned[0]
    assert not lock.exists() and not list(cache.glob("*.lock"))
    assert "2 cells, 1 cached, 1 run, 0 failed" in out
    tally("caches and report folders", "accepted")


def test_waiting_for_a_live_lock_says_whose_and_how_old(work, capsys, monkeypatch) -> None:
    """A young lock of a process on another host is waited for (it may be computing the cell), and the study says
    so: the lock file, its holder's pid and host, its age.  When the holder lets go, the study computes the cell.
    Before: the progress bar said 'waiting for another process' and nothing else."""
    key = _alpha_key(work, 3)
    cache = work / "out" / "cache"
    (cache / f"{key}.json").unlink()
    lock = _write_lock(cache, key, 4243, "elsewhere", time.time() - 90)
    monkeypatch.setattr(cache_module, "WAIT_FIRST_NOTICE_S", 1.0)  # (10 s in use: a short wait is not worth a line)
    release = threading.Timer(3.0, lock.unlink)
    release.start()
    try:
        with deadline(60):
            code, out, err = _run(["study", "alpha.toml", "--out", "out"], capsys)
    finally:
        release.cancel()
    assert code == 0, err[-1500:]
    said = [line for line in err.splitlines() if line.startswith("pcverify: waiting for another process: ")]
    assert said and str(Path("out") / "cache" / f"{key}.lock") in said[0], err
    assert "held by pid 4243 on host elsewhere for 9" in said[0] and "older than 2.0 h" in said[0]
    assert "1 cached, 1 run" in out and not list(cache.glob("*.lock"))
    tally("caches and report folders", "accepted")


def test_a_cache_entry_nested_100000_deep_is_recomputed(work, capsys) -> None:
    key = _alpha_key(work, 2)
    entry = work / "out" / "cache" / f"{key}.json"
    entry.write_text(json.dumps({"key": key, "sha256": "0", "result": None})[:-5] + NESTED + "}")
    code, out, err = _run(["study", "alpha.toml", "--out", "out"], capsys)
    assert code == 0 and "Traceback" not in err, err[-1500:]
    assert f"cache entry {key} " in err and "is corrupt: not valid JSON (nested too deeply" in err, err
    assert "1 corrupt entries recomputed" in out and json.loads(entry.read_text())["key"] == key
    tally("caches and report folders", "accepted")


def _second_study_folder(work: Path) -> Path:
    """out/alpha2: a copy of alpha's report under another name whose study file is gone (kept as it is)."""
    folder = work / "out" / "alpha2"
    shutil.copytree(work / "out" / "alpha", folder)
    doc = json.loads((folder / "manifest.json").read_text())
    (folder / "manifest.json").write_text(json.dumps(doc | {"name": "alpha2", "study_file": None}))
    records = json.loads((folder / "verdicts.json").read_text())
    (folder / "verdicts.json").write_text(json.dumps([r | {"study": "alpha2"} for r in records]))
    return folder


@pytest.mark.parametrize("which", ["manifest", "verdicts.json", "benchmark run"])
def test_report_files_nested_100000_deep_are_skipped_with_a_warning(work, capsys, which) -> None:
    folder = _second_study_folder(work)
    path = {"manifest": folder / "manifest.json", "verdicts.json": folder / "verdicts.json",
            "benchmark run": work / "out" / "benchmarks" / "Linux-CPython" / "0001_nested.json"}[which]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(NESTED)
    code, out, err = _run(["report", "--out", "out"], capsys)
    assert code == 0 and "Traceback" not in err, err[-1500:]
    relative = path.relative_to(work)
    assert any(f"{relative} is not valid JSON (nested too deeply" in w for w in _warnings(err)), err
    index = (work / "out" / "index.html").read_text()
    assert "id='alpha'" in index and ("id='alpha2'" in index) == (which != "manifest")
    tally("caches and report folders", "accepted")


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory) -> Path:
    """The synthetic calibration study run once: its cells cached, its report with the calibration's claim."""
    root = tmp_path_factory.mktemp("files-calibration")
    (root / "calib.toml").write_text(CALIBRATION)
    with contextlib.chdir(root):
        assert main(["study", "calib.toml", "--out", "out", "--json"]) == 0
    records = json.loads((root / "out" / "calib" / "verdicts.json").read_text())
    assert [r["verdict"] for r in records] == ["pass"]  # with every cell cached
    return root


@pytest.fixture
def one_cell_lost(calibrated, tmp_path, monkeypatch, capsys) -> tuple[Path, str, str, str]:
    """A copy of the calibrated report whose cache lost one cell; `report` run on it: (folder, lost cell's key,
    stdout, stderr)."""
    shutil.copytree(calibrated, tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    entries = sorted((tmp_path / "out" / "cache").glob("*.json"))
    assert len(entries) >= 12
    lost = entries[len(entries) // 2]
    lost.unlink()
    code, out, err = _run(["report", "--out", "out"], capsys)
    assert code == 0 and "Traceback" not in err, err[-1500:]
    return tmp_path, lost.stem, out, err


def test_report_says_a_calibration_is_not_rebuilt(one_cell_lost) -> None:
    """Before: `calib: rebuilt from 0 cached cells`, not a word about the calibration."""
    _, _, out, _ = one_cell_lost
    line = next(line for line in out.splitlines() if line.startswith("calib:"))
    assert "calibration quad:" in line and "is not cached" in line and "calibration not rebuilt" in line, out
    assert "its claims fail" in line
    tally("caches and report folders", "accepted")


def test_a_calibration_not_rebuilt_keeps_its_section_saying_so(one_cell_lost) -> None:
    """Before: the calibration's section was dropped from the manifest and the page without a word."""
    work, _, _, _ = one_cell_lost
    manifest = json.loads((work / "out" / "calib" / "manifest.json").read_text())
    section = next((s for s in manifest["sections"] if s["id"] == "quad"), None)
    assert section is not None and "NOT REBUILT" in section["title"] and "is not cached" in section["title"]
    assert "quad-not-rebuilt.csv" in section["tables"]
    assert "NOT REBUILT" in (work / "out" / "index.html").read_text()
    tally("caches and report folders", "accepted")


def test_a_calibration_not_rebuilt_fails_its_claims_naming_the_cell(one_cell_lost) -> None:
    """The claim on the calibration's validation table fails, and its note names the missing cell (before: the
    note said only that the table had no rows)."""
    work, _, _, _ = one_cell_lost
    records = json.loads((work / "out" / "calib" / "verdicts.json").read_text())
    assert [r["claim"] for r in records] == ["quad-validated"] and records[0]["verdict"] == "fail"
    assert "is not cached" in records[0]["note"] and "calibration quad" in records[0]["note"], records[0]
    tally("caches and report folders", "accepted")


def _foreign(work: Path, folder: str, declares: str, plugin: str) -> Path:
    """out/FOLDER/manifest.json (a valid manifest of study FOLDER) naming evil.toml, which declares study
    `declares` with a plugin module that leaves a file when imported."""
    (work / f"{plugin}.py").write_text(MARKER_PLUGIN.format(name=plugin.replace("_", "-")))
    evil = work / f"{plugin}.toml"
    evil.write_text(f'name = "{declares}"\ntitle = "EVIL"\nplugins = ["{plugin}"]\n'
                    + ALPHA.split("\n", 2)[2].replace("n = [2, 3]", "n = [2]"))
    (work / "out" / folder).mkdir(exist_ok=True)
    manifest = {"name": folder, "title": "a study", "sections": [], "verdicts": None, "study_file": str(evil),
                "plugins": [], "command": "pcverify study evil.toml"}
    (work / "out" / folder / "manifest.json").write_text(json.dumps(manifest))
    return work / f"{plugin}.imported"


def test_a_manifest_cannot_rewrite_another_studys_report(work, capsys, monkeypatch) -> None:
    """out/x/manifest.json names a file that declares study alpha: before, `report` loaded it (importing its
    plugin) and rewrote alpha's report from it (title EVIL, one cell)."""
    monkeypatch.syspath_prepend(str(work))
    before = (work / "out" / "alpha" / "cells.csv").read_bytes()
    imported = _foreign(work, "x", "alpha", "evil_x")
    code, _, err = _run(["report", "--out", "out"], capsys)
    assert code == 0, err[-1500:]
    warned = [w for w in _warnings(err) if "out/x/manifest.json names study file" in w]
    assert len(warned) == 1 and "declares study 'alpha', not 'x'" in warned[0] and "not loaded" in warned[0], err
    assert not imported.exists()
    assert json.loads((work / "out" / "alpha" / "manifest.json").read_text())["title"] != "EVIL"
    assert (work / "out" / "alpha" / "cells.csv").read_bytes() == before
    tally("caches and report folders", "rejected")


def test_a_manifest_cannot_make_report_run_a_study_into_a_new_folder(work, capsys, monkeypatch) -> None:
    """out/y/manifest.json names a file that declares study zeta: before, its plugin was imported and out/zeta
    written."""
    monkeypatch.syspath_prepend(str(work))
    imported = _foreign(work, "y", "zeta", "evil_y")
    code, _, err = _run(["report", "--out", "out"], capsys)
    assert code == 0 and any("declares study 'zeta', not 'y'" in w for w in _warnings(err)), err[-1500:]
    assert not imported.exists() and not (work / "out" / "zeta").exists()
    tally("caches and report folders", "rejected")


def test_a_manifest_cannot_replace_a_shipped_study(work, capsys, monkeypatch) -> None:
    """out/stability/manifest.json names a user file that also calls itself stability: before, it replaced the
    shipped study's report; now the shipped file is the only source of a shipped study."""
    monkeypatch.syspath_prepend(str(work))
    imported = _foreign(work, "stability", "stability", "evil_s")
    code, _, err = _run(["report", "--out", "out"], capsys)
    assert code == 0 and any("for the shipped study 'stability'" in w for w in _warnings(err)), err[-1500:]
    assert not imported.exists()
    assert json.loads((work / "out" / "stability" / "manifest.json").read_text())["title"] != "EVIL"
    tally("caches and report folders", "rejected")


@pytest.mark.parametrize("how", ["declared, 300 characters", "file name, 100 characters", "file name, a dot first"])
def test_a_study_name_unfit_for_a_folder_is_one_error_line(work, capsys, how) -> None:
    """A name becomes the report's folder: 1 to 80 letters, digits, '.', '_', '-', not starting with a dot.
    (The declared name was refused already at the start of this branch; a name taken from the file name was
    not: a 100-character one made its folder, a '.hidden' one a report the index never showed.)"""
    if how.startswith("declared"):
        path = work / "long.toml"
        path.write_text(ALPHA.replace('name = "alpha"', f'name = "{"s" * 300}"'))
    else:
        path = work / (("s" * 100 + ".toml") if "100" in how else ".hidden.toml")
        path.write_text(ALPHA.replace('name = "alpha"\n', ""))
    before = sorted(p.name for p in (work / "out").iterdir())
    code, _, err = _run(["study", path.name, "--out", "out"], capsys)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("pcverify: error: study file"), err[-1500:]
    assert "allowed: 1 to 80 letters, digits, '.', '_' or '-', starting with a letter or digit" in lines[0]
    assert sorted(p.name for p in (work / "out").iterdir()) == before  # no folder made for it
    tally("caches and report folders", "rejected")


# ----------------------------------------------------------------------------- signals
def _plugins(work: Path) -> dict[str, str]:
    """The environment of a subprocess that imports the plugins in `work` and tests/ (calib_synthetic)."""
    (work / "slowplug.py").write_text(SLOW_PLUGIN)
    return ENV | {"PYTHONPATH": os.pathsep.join([str(work), str(TESTS), ENV.get("PYTHONPATH", "")])}


def _wait_for_file(path: Path, proc: subprocess.Popen, seconds: float = 120.0) -> None:
    end = time.monotonic() + seconds
    while not path.exists():
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < end, f"{path} never appeared"
        time.sleep(0.05)


def _terminated(proc: subprocess.Popen) -> str:
    """SIGTERM to the command's process group; its stderr, after asserting exit 143, one line, no traceback."""
    os.killpg(proc.pid, signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    lines = err.strip().splitlines()
    assert proc.returncode == 143, (proc.returncode, err[-1500:])
    assert lines and lines[-1].startswith("pcverify: terminated") and "Traceback" not in err, err[-1500:]
    return err


def test_sigterm_while_a_plugin_imports_is_one_line_and_exit_143(work) -> None:
    """`run --solver slowplug:Slow`, SIGTERM while the plugin's import sleeps.  Before: killed silently (-15)."""
    env = _plugins(work) | {"PCV_SLOW_IMPORT": str(work / "importing")}
    proc = popen("run", "bar-heat-faces", "--solver", "slowplug:Slow", "--n", "2", cwd=work, env=env)
    _wait_for_file(work / "importing", proc)
    _terminated(proc)
    tally("signals", "accepted")


def test_sigterm_while_report_rebuilds_is_one_line_and_leaves_every_file_whole(work, capsys, monkeypatch) -> None:
    """`report` over alpha and a study whose plugin import sleeps; SIGTERM then: exit 143 with the one line, no
    temporary file left, every JSON file of the report whole.  Before: killed silently (-15)."""
    env = _plugins(work)
    monkeypatch.syspath_prepend(str(work))
    (work / "slowy.toml").write_text('name = "slowy"\nplugins = ["slowplug"]\n[[group]]\nid = "g"\n'
                                     'scene = "bar-heat-faces"\nsolvers = ["slow-quadratic"]\nn = [2]\n')
    assert _run(["study", "slowy.toml", "--out", "out"], capsys)[0] == 0
    proc = popen("report", "--out", "out", cwd=work, env=env | {"PCV_SLOW_IMPORT": str(work / "importing")})
    _wait_for_file(work / "importing", proc)
    _terminated(proc)
    out = work / "out"
    assert not [p for p in out.rglob("*") if p.name.endswith(".tmp")]
    for path in [p for p in out.rglob("*.json") if p.parent.name != "cache"]:
        json.loads(path.read_text())  # whole: the old file or the new one
    assert not list((out / "cache").glob("*.lock"))
    tally("signals", "accepted")


def test_sigterm_stops_a_study_started_with_sigint_ignored_and_leaves_no_lock(work) -> None:
    """`sh -c 'cmd &'` starts the study with SIGINT ignored; before, it then got no SIGTERM handler either, so a
    SIGTERM killed it silently (-15) and left its cell's lock behind."""
    (work / "sleepy.toml").write_text('name = "sleepy"\nplugins = ["calib_synthetic"]\n[[group]]\nid = "g"\n'
                                      'scene = "bar-heat-faces"\nsolvers = ["calib-quadratic"]\n'
                                      'solver_params = { sleep = 10.0 }\nn = [2]\n')
    cache = work / "out" / "cache"
    proc = subprocess.Popen(["sh", "-c", 'trap "" INT; exec "$@"', "sh", *COMMAND, "study", "sleepy.toml", "--out",
                             "out"], cwd=work, env=_plugins(work), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    end = time.monotonic() + 120
    while not list(cache.glob("*.lock")):  # the cell is being computed
        assert proc.poll() is None and time.monotonic() < end, proc.communicate()
        time.sleep(0.05)
    _terminated(proc)
    assert not list(cache.glob("*.lock")) and not list(cache.glob(".*.tmp"))
    tally("signals", "accepted")


BENCHMARK = """import os
import time


def test_tiny(benchmark):
    benchmark.pedantic(time.sleep, args=(float(os.environ["TINY_DELAY"]),), rounds=3, iterations=1)
"""


def test_a_benchmark_regression_is_one_line_naming_it(work) -> None:
    """The second run of a benchmark is 20 times slower: one line naming the benchmark, the field, by how much
    and the allowed limit, exit 1.  Before: a PerformanceRegression traceback."""
    (work / "bench").mkdir()
    (work / "bench" / "test_tiny.py").write_text(BENCHMARK)
    env = {k: v for k, v in ENV.items() if not k.startswith("PYTEST_")}  # not an xdist worker: timing stays on
    first = cli("bench", "--tests", "bench", "--storage", "saved", cwd=work, env=env | {"TINY_DELAY": "0.001"})
    assert first.returncode == 0, first.stderr[-1500:]
    second = cli("bench", "--tests", "bench", "--storage", "saved", cwd=work, env=env | {"TINY_DELAY": "0.02"})
    lines = second.stderr.strip().splitlines()
    assert second.returncode == 1 and "Traceback" not in second.stderr, second.stderr[-1500:]
    assert lines[-1].startswith("pcverify: benchmark regression against 0001_"), lines[-1]
    assert "test_tiny mean +" in lines[-1] and "(allowed: at most +25 %)" in lines[-1]
    tally("signals", "accepted")


def test_zz_files_tally() -> None:
    check_tally({"caches and report folders": 18, "signals": 4})


def test_a_lock_is_stale_only_after_twice_the_cell_time_limit(tmp_path) -> None:
    """The default stale age is twice the default cell time limit, and a study allowed a longer time limit
    raises it, so the lock of a cell still computing within its limit is never taken over."""
    assert cache_module.STALE_LOCK_S == 2 * DEFAULT_TIME_LIMIT
    (tmp_path / "s.toml").write_text('name = "s"\n[[group]]\nid = "g"\nscene = "bar-heat-faces"\n'
                                     'solvers = ["skfem"]\nn = [2]\n')
    cache = cache_module.Cache(tmp_path / "cache")
    execute(load_study(str(tmp_path / "s.toml")), cache, progress=False, time_limit=3 * 3600.0)
    assert cache.stale_after == 6 * 3600.0
