"""Machine-readable verdicts and the CI gate: verdicts.json, `study --json`, `--strict`, `--group`, and the
command each verdict carries reproducing its number."""

import json
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pcverify.harness.cli import main

STUDY = """
name = "gate"
title = "a passing and a failing claim"
[[group]]
id = "faces"
title = "steady faces, scikit-fem"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["skfem"]
n = [2, 3]
[[group]]
id = "paper"
title = "the paper's corners, scikit-fem"
analysis = "table"
scene = "bar-heat-paper"
scene_params = { placement = "diagonal" }
solvers = ["skfem"]
n = [2]
[[claim]]
id = "exact-line"
text = "scikit-fem reproduces the steady linear profile"
table = "faces-cells"
per = "n"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
uncertainty = 1e-12
[[claim]]
id = "wrong-mean"
text = "the volume mean of the faces scene is 0.6 (false: it is 1/2)"
table = "faces-cells"
metric = "volume_mean"
reference = "analytic"
target = 0.6
tolerance = 0.01
"""
KEYS = ("study", "claim", "case", "reference", "value", "target", "error", "uncertainty", "tolerance", "verdict",
        "note", "command")
EXE = shutil.which("pcverify") or str(Path(sys.executable).with_name("pcverify"))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("gate")
    path = folder / "gate.toml"
    path.write_text(STUDY)
    return path


def _run(capsys, *argv):
    code = main(["study", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_json_and_verdicts_file_list_every_verdict(study, tmp_path, capsys):
    out = tmp_path / "reports"
    code, stdout, _ = _run(capsys, study, "--out", out, "--json")
    assert code == 0  # a failing claim is a finding, not an error, without --strict
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary[0]["cells"] == 3  # the per-study counts are kept
    printed = summary[0]["verdicts"]
    written = json.loads((out / "verdicts.json").read_text())
    assert printed == written == json.loads((out / "gate" / "verdicts.json").read_text())
    for record in written:
        assert set(KEYS) <= set(record)
    by = {(r["claim"], r["case"]): r for r in written}
    assert [by[("exact-line", f"n={n}")]["verdict"] for n in (2, 3)] == ["pass", "pass"]
    wrong = by[("wrong-mean", "")]
    assert wrong["verdict"] == "fail" and wrong["value"] == pytest.approx(0.5, abs=1e-9)
    assert wrong["error"] == pytest.approx(0.1, abs=1e-9) and wrong["uncertainty"] is None
    # a value from several cells is reproduced by `pcverify verdict`; one error of a single cell by `pcverify run`
    assert wrong["command"] == f"pcverify verdict {study} wrong-mean"
    assert by[("exact-line", "n=3")]["command"] == "pcverify run bar-heat-faces --solver skfem --n 3"
    assert by[("exact-line", "n=3")]["nodes"] == 63  # 3 x 3 x 7 lattice nodes


def test_strict_exits_1_and_lists_the_failed_claims(study, tmp_path):
    """The console script as a CI runs it: exit 0 without --strict, 1 with it, failures on stderr."""
    out = tmp_path / "reports"
    plain = subprocess.run([EXE, "study", str(study), "--out", str(out)], capture_output=True, text=True,
                           timeout=600, check=False)
    assert plain.returncode == 0, plain.stderr
    strict = subprocess.run([EXE, "study", str(study), "--out", str(out), "--strict"], capture_output=True,
                            text=True, timeout=600, check=False)
    assert strict.returncode == 1
    lines = strict.stderr.strip().splitlines()
    assert any("claim fail: gate/wrong-mean" in x and f"reproduce: pcverify verdict {study} wrong-mean" in x
               for x in lines)
    assert not any("exact-line" in x for x in lines) and "1 of 3 verdicts are not a pass" in lines[-1]


def test_group_selector_runs_one_group_with_its_claims(study, tmp_path, capsys):
    out = tmp_path / "reports"
    code, stdout, _ = _run(capsys, study, "--out", out, "--json", "--group", "paper")
    assert code == 0
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary[0]["cells"] == 1 and summary[0]["verdicts"] == []  # no claim reads the paper group
    manifest = json.loads((out / "gate" / "manifest.json").read_text())
    assert [s["id"] for s in manifest["sections"]] == ["paper"]
    code, stdout, _ = _run(capsys, study, "--out", out, "--json", "--group", "faces", "--strict")
    assert code == 1 and len(json.loads(stdout.strip().splitlines()[-1])[0]["verdicts"]) == 3
    manifest = json.loads((out / "gate" / "manifest.json").read_text())
    assert [s["id"] for s in manifest["sections"]] == ["paper", "faces"]  # merged: the paper group stays
    code, _, err = _run(capsys, study, "--out", out, "--group", "nope")
    assert code == 2 and "group='nope' is unknown" in err and "faces, paper" in err
    code, _, err = _run(capsys, "default", "--out", out, "--group", "faces", "--dry-run")
    assert code == 2 and "--group needs one study" in err


def test_a_group_run_never_removes_the_other_groups_verdicts(study, tmp_path, capsys):
    """Checking one number with --group keeps the rest of the report: every claim's verdict is still there."""
    out = tmp_path / "reports"
    assert _run(capsys, study, "--out", out)[0] == 0
    full = json.loads((out / "gate" / "verdicts.json").read_text())
    assert _run(capsys, study, "--out", out, "--group", "paper")[0] == 0
    assert json.loads((out / "gate" / "verdicts.json").read_text()) == full
    assert [s["id"] for s in json.loads((out / "gate" / "manifest.json").read_text())["sections"]] == ["faces", "paper"]
    assert json.loads((out / "verdicts.json").read_text()) == full


def test_run_command_only_for_what_every_pcverify_process_knows():
    from pcverify.harness.report.reproduce import run_command

    cell = {"scene": "bar-heat-patch", "solver": "fipy", "n": 3, "refine": 4, "scene_params": {"rho": 0.002},
            "solver_params": {}}
    assert run_command(cell) == "pcverify run bar-heat-patch --solver fipy --n 3 --refine 4 --set rho=0.002"
    assert run_command(cell | {"scene_params": {"t_max": 400.0}, "solver_params": {"scheme": "crank-nicolson"}}) == (
        "pcverify run bar-heat-patch --solver fipy --n 3 --refine 4 --set t_max=400.0 --set scheme=crank-nicolson")
    assert run_command(cell | {"solver": "not-installed"}) is None  # e.g. registered by a study's plugin module
    assert run_command(cell | {"scene": "not-in-the-catalogue"}) is None  # e.g. a study file's [[scene]]


REPRODUCE = """
name = "reproduce"
title = "every kind of verdict command"
[[group]]
id = "steady"
title = "steady faces, both continuum solvers"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["skfem", "fipy"]
n = [2, 3]
[[group]]
id = "transient"
title = "transient faces, scikit-fem at three n"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.2, dt = 0.01 }
solvers = ["skfem"]
n = [3, 4, 5]
solver_params = { scheme = "crank-nicolson" }
[[claim]]
id = "line"
text = "one error of one cell"
table = "steady-cells"
select = { solver = "skfem" }
per = "n"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
[[claim]]
id = "largest-mean"
text = "an aggregate over cells"
table = "steady-cells"
metric = "volume_mean"
reference = "analytic"
target = 0.5
tolerance = 1e-9
[[claim]]
id = "same-grid"
text = "a difference from other rows"
table = "steady-cells"
select = { solver = "skfem" }
against = { solver = "fipy" }
per = "n"
metric = "bulk_median"
reference = "same-grid"
tolerance = 1e-9
[[claim]]
id = "order"
text = "a fitted order"
table = "transient-fits"
select = { quantity = "nodes.l2" }
metric = "order"
reference = "analytic"
target = 2.0
tolerance = 1.0
"""


def test_the_command_of_every_verdict_prints_its_number(tmp_path, monkeypatch, capsys):
    """Run the command printed beside each verdict of a small study, as a user would from the study's folder,
    and find the verdict's value, to the last digit, in what it prints: `pcverify run` for one error of one
    cell (with the errors against the reference), `pcverify verdict` for aggregates, differences and fits."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "reproduce.toml").write_text(REPRODUCE)
    assert main(["study", "reproduce.toml"]) == 0
    records = json.loads((tmp_path / "reports" / "verdicts.json").read_text())
    assert len(records) == 6 and all(r["value"] is not None for r in records)
    kinds = set()
    for r in records:
        argv = shlex.split(r["command"])
        assert argv[0] == "pcverify"
        kinds.add(argv[1])
        capsys.readouterr()
        main(argv[1:])
        printed = capsys.readouterr().out
        numbers = [float(x) for x in re.findall(r"-?\d+\.\d+(?:e[-+]?\d+)?|-?\d+e[-+]?\d+", printed)]
        assert r["value"] in numbers, (r["claim"], r["case"], r["command"], printed[-800:])
    assert kinds == {"run", "verdict"}
    line = next(r for r in records if r["claim"] == "line" and r["case"] == "n=3")
    assert line["command"] == "pcverify run bar-heat-faces --solver skfem --n 3"
