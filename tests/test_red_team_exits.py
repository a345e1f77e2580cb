"""Red team, exits: every command ends in one of its documented ways.  A --time-limit beyond what the worker's
wait can take is refused in one line (poll() waits at most 2^31 - 1 ms); a plugin that calls sys.exit, at import
or inside a command, never makes a `--json` command exit 0 without its JSON; a SIGTERM after a command has ended
still prints the "terminated" line and exits 143; a mutant that expects a claim its study lacks is one line."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from red_team import ENV, check_tally, cli, one_line_error, run, tally

from pcverify.harness import cli as cli_module
from pcverify.harness.run.limits import MAX_TIME_LIMIT


def test_a_time_limit_beyond_what_a_wait_can_take_is_one_line(tmp_path, capfd) -> None:
    """30 days raised OverflowError from the worker's poll(); the longest allowed, 24 days, runs."""
    assert MAX_TIME_LIMIT < (2**31 - 1) / 1000.0
    for command in (["run", "bar-heat-faces", "--solver", "skfem", "--n", "2"], ["study", "missing.toml"]):
        done = run(*command, "--time-limit", "2592000", cwd=tmp_path, capfd=capfd)
        assert done.returncode == 2
        assert "--time-limit: time-limit='2592000' is not valid; allowed: seconds in (0, 2.0736e+06]" in \
            one_line_error(done)
    done = run("run", "bar-heat-faces", "--solver", "skfem", "--n", "2", "--time-limit", f"{MAX_TIME_LIMIT:g}",
               "--json", cwd=tmp_path, capfd=capfd)
    assert done.returncode == 0 and json.loads(done.stdout)["status"] == "ok"
    tally("exits", "rejected")


def _distribution(where: Path, group: str, name: str, module: str, body: str) -> dict[str, str]:
    """A distribution on PYTHONPATH (a .dist-info folder and its module) with one entry point; the environment."""
    info = where / "fake_exit-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-exit\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(f"[{group}]\n{name} = {module}\n")
    (where / f"{module.partition(':')[0]}.py").write_text(textwrap.dedent(body))
    return {**ENV, "PYTHONPATH": os.pathsep.join([str(where), ENV.get("PYTHONPATH", "")])}


def test_an_entry_point_that_exits_at_import_leaves_the_json_whole(tmp_path) -> None:
    """`scenes --json` exited 0 with nothing on stdout: the scene is listed as unavailable with the reason."""
    env = _distribution(tmp_path / "ep", "pcverify.scenes", "exiter", "exiter_mod:SPEC", "import sys\nsys.exit(0)\n")
    done = cli("scenes", "--json", cwd=tmp_path, env=env)
    assert done.returncode == 0, done.stderr
    (entry,) = [s for s in json.loads(done.stdout) if s["name"] == "exiter"]
    assert entry["available"] is False and entry["reason"].endswith("is unavailable: SystemExit: 0")
    tally("exits", "accepted")


def test_sys_exit_inside_a_command_is_one_line_and_no_success(tmp_path, capfd, monkeypatch) -> None:
    """Plugin code reached by a command that calls sys.exit(0) (the guarded places, a plugin's import, its
    supports, estimate or constructor, already turn it into a failed cell or a one-line error): whatever code
    does it, the command line says so in one line and exits 2, never 0 without output."""
    (tmp_path / "quits.py").write_text("import sys\n\n\ndef anywhere(args):\n    sys.exit(0)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import quits  # noqa: PLC0415 - a module made by this test

    monkeypatch.setattr(cli_module, "command", lambda name: quits.anywhere)
    done = run("scenes", "--json", cwd=tmp_path, capfd=capfd)
    assert done.stdout == ""
    line = one_line_error(done)
    assert f"the command was ended by sys.exit(0) in {tmp_path / 'quits.py'}:5, before it finished" in line
    tally("exits", "rejected")


def test_a_sigterm_after_the_command_ended_prints_its_line(tmp_path) -> None:
    """Between a command's end and the process's exit SIGTERM had its default action: rc -15, no line."""
    script = ("import os, signal, sys, time\nsys.argv = ['pcverify']\nfrom pcverify.harness.cli import main\n"
              "code = main(['scenes'])\nos.kill(os.getpid(), signal.SIGTERM)\ntime.sleep(30)\nsys.exit(code)\n")
    done = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True, env=ENV,
                          timeout=120, check=False)
    assert done.returncode == 128 + signal.SIGTERM
    assert done.stderr.strip().splitlines()[-1] == ("pcverify: terminated (after the command had ended: what it wrote "
                                                    "is complete)")
    tally("exits", "accepted")


def test_a_mutant_that_expects_an_unknown_claim_is_one_line(tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text(textwrap.dedent('''
        name = "s"

        [[group]]
        id = "steady"
        scene = "bar-heat-faces"
        solvers = ["skfem"]
        n = [2]

        [[claim]]
        id = "exact"
        text = "Q1 holds the linear profile"
        table = "steady-cells"
        metric = "err.nodes.linf"
        reference = "analytic"
        target = 0.0
        tolerance = 1e-9
        tolerance_basis = "derived: round-off"
        sense = "at-most"

        [[mutant]]
        name = "m"
        file = "solvers/continuum/skfem_heat.py"
        find = "a"
        replace = "b"
        breaks = "something"
        expect = ["no-such-claim"]
    '''))
    done = run("mutate", "s.toml", "--out", str(tmp_path / "out"), cwd=tmp_path, capfd=capfd)
    assert done.returncode == 2
    assert ("mutant 'm' (study file s.toml): expect = 'no-such-claim' is not a claim of the study; allowed: one of "
            "exact") in one_line_error(done)
    tally("exits", "rejected")


def test_zz_exits_tally() -> None:
    check_tally({"exits": 5})
