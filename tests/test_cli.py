"""The command line as a newcomer uses it: help, scenes, errors as one line with exit code 2."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pcverify.harness.cli import main


def test_help_lists_commands(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for word in ("scenes", "solvers", "run", "study", "report", "--set KEY=VALUE"):
        assert word in out


def test_scenes_json_lists_catalogue(capsys):
    assert main(["scenes", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    names = [r["name"] for r in rows]
    assert names[:3] == ["bar-heat-paper", "bar-heat-patch", "bar-heat-faces"]
    rho = [p for p in rows[1]["parameters"] if p["name"] == "rho"][0]
    assert rho["default"] == 0.001 and rho["unit"] == "m" and "0.004" in rho["allowed"]


@pytest.mark.parametrize(
    "argv, word",
    [
        (["run", "bar-heat-nope", "--solver", "skfem"], "scene='bar-heat-nope'"),
        (["run", "bar-heat-paper", "--solver", "nope"], "solver='nope'"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "placement=front"], "placement"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "t_max=nan"], "t_max"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "bogus=1"], "bogus"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--set", "novalue"], "KEY=VALUE"),
        (["run", "bar-heat-paper", "--solver", "skfem", "--n", "1"], "n=1"),
    ],
)
def test_bad_input_is_one_line_error(argv, word, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("pcverify: error:") and word in err
    assert "\n" not in err and "Traceback" not in err


@pytest.mark.parametrize("solver", ["skfem", "fipy"])
def test_run_json_contract_end_to_end(solver):
    """The console script as a user calls it: one JSON object with the public keys, exact linear profile."""
    import shutil
    import subprocess
    import sys

    import numpy as np

    exe = shutil.which("pcverify") or str(__import__("pathlib").Path(sys.executable).with_name("pcverify"))
    proc = subprocess.run([exe, "run", "bar-heat-faces", "--solver", solver, "--n", "3", "--json"],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    for key in ("scene", "solver", "params", "resolution", "unknowns", "wall_s", "status", "samples", "summary"):
        assert key in out
    assert out["status"] == "ok" and out["resolution"]["n"] == 3 and out["resolution"]["h"] == pytest.approx(0.005)
    assert set(out["samples"]) == {"nodes", "front_top_edge", "bottom_back_edge"}
    edge = out["samples"]["front_top_edge"]
    z = np.asarray(edge["points"])[:, 2]
    # the steady profile is linear: both discretisations are exact for it, up to round-off
    assert np.max(np.abs(np.asarray(edge["values"]) - (1 - z / 0.03))) < 1e-9
    assert out["summary"]["volume_mean"] == pytest.approx(0.5, abs=1e-9)


def test_a_reader_that_stops_early_is_not_an_error() -> None:
    """`pcverify study default --dry-run --json | head -c 1` (~150 kB, more than a pipe holds): the reader closes
    the pipe after the first bytes.  Before: 'pcverify: error: [Errno 32] Broken pipe' on stderr and exit 2; now
    nothing on stderr and 141, as a shell reports a SIGPIPE."""
    proc = subprocess.Popen([sys.executable, "-m", "pcverify.harness.cli", "study", "default", "--dry-run", "--json"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, bufsize=0)
    assert proc.stdout.read(1)  # the first byte is there: the reader leaves
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 141 and err == "", err


def test_a_slow_run_into_a_pipe_leaves_no_progress_text_on_stderr() -> None:
    """A run of 2.5 s with stderr a pipe (a log, a CI job): the elapsed-time indicator, shown on a terminal after
    2 s, stood in front of what followed (the result's messages, a one-line error) as 'calib-quadratic on ...:
    00:02 elapsed' and a carriage return.  Now it is shown on a terminal only."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parent)}
    out = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "run", "bar-heat-faces", "--solver",
                          "calib_synthetic:Quadratic", "--n", "2", "--set", "solver.sleep=2.5"],
                         capture_output=True, text=True, env=env, timeout=300, check=False)
    assert out.returncode == 0, out.stderr[-1500:]
    assert "elapsed" not in out.stderr and "\r" not in out.stderr, out.stderr
