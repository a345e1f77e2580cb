"""The compare step: a cell's errors against its scene's reference are computed once, right after the solve,
stored with the cell and covered by its key; `pcverify run` goes through the study's cell path, so it prints
those errors and reproduces a study cell bit for bit, also one whose arithmetic depends on BLAS threads."""

from __future__ import annotations

import json
import math
import os
import shlex
import subprocess
import sys
from pathlib import Path

import pandas as pd
from lint_imports import installed_layout

from pcverify.harness.cli import main
from pcverify.harness.judge import compare
from pcverify.harness.judge.tables import cells_table
from pcverify.harness.report.reproduce import run_command, select_groups
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import cell_identity, execute
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import Group, Study, load_study
from pcverify.references import heat

REPO = Path(__file__).resolve().parent.parent
TIMES = ("wall_s", "kernel_s", "kernel_cpu_s", "kernel_wall_s")


def test_run_prints_the_errors_the_study_stores(tmp_path, capsys) -> None:
    """`pcverify run bar-heat-faces --solver skfem --n 3 --json` has errors.nodes.l2 equal to err.nodes.l2 of
    that cell in the study continuum-heat (group faces-steady); Q1 holds the steady line exactly (~1e-16),
    and the text output has one line per sample set with its errors and reference kind."""
    assert main(["run", "bar-heat-faces", "--solver", "skfem", "--n", "3", "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    study = select_groups(load_study("continuum-heat"), ["faces-steady"])
    results, _ = execute(study, Cache(tmp_path / "cache"), progress=False)
    cells = cells_table(results).set_index(["solver", "n"])
    assert set(run["errors"]) == {"nodes", "front_top_edge", "bottom_back_edge"}
    for name, e in run["errors"].items():
        assert e["reference"] == "analytic" and e["l2"] < 1e-15 and e["linf"] < 2e-15, (name, e)
        assert e["l2"] == cells.loc[("skfem", 3), f"err.{name}.l2"]
        assert e["linf"] == cells.loc[("skfem", 3), f"err.{name}.linf"]
    assert main(["run", "bar-heat-faces", "--solver", "skfem", "--n", "3"]) == 0
    text = capsys.readouterr().out
    lines = [line for line in text.splitlines() if line.strip().startswith("error ")]
    assert len(lines) == 3 and all("against the analytic reference" in line for line in lines), text
    assert f"l2 {run['errors']['nodes']['l2']!r}" in next(line for line in lines if "error nodes" in line)


def _without_times(result: dict) -> dict:
    summary = {k: v for k, v in result["summary"].items() if k not in TIMES}
    return {"status": result["status"], "reason": result["reason"], "summary": summary,
            "samples": result["samples"], "errors": result["errors"], "unknowns": result["unknowns"]}


def test_run_reproduces_a_blas_dependent_study_cell(tmp_path) -> None:
    """heat-particles, group paper-all: the macromolecule on the paper's bar at n = 4 (a chaotic lattice: its
    ARPACK set-up differs in the last bits with the number of BLAS threads, and the run amplifies that).  The
    command a verdict prints for that cell, run without OMP/OPENBLAS_NUM_THREADS in its environment, gives the
    study cell's numbers bit for bit (before: bulk_median 0.0322 against the study's 0.0411)."""
    paper = next(g for g in load_study("heat-particles").groups if g.id == "paper-all")
    cell = next(c for c in paper.cells if c.solver == "macromolecule" and c.n == 4)
    one = Study("one-cell", "one cell", [Group(paper.id, paper.title, paper.analysis, [cell], paper.options)])
    results, _ = execute(one, Cache(tmp_path / "cache"), progress=False)
    study_cell = results[0]
    command = run_command(study_cell)
    assert command == "pcverify run bar-heat-paper --solver macromolecule --n 4"
    env = {k: v for k, v in os.environ.items() if k not in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                                                            "MKL_NUM_THREADS")}
    done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", *shlex.split(command)[1:], "--json"],
                          capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    run = json.loads(done.stdout)
    assert run["summary"]["bulk_median"] == study_cell["summary"]["bulk_median"]
    assert _without_times(run) == _without_times(study_cell)


STUDY = """
name = "stored-errors"
title = "tables from the stored errors"

[[group]]
id = "steady"
scene = "bar-heat-faces"
solvers = ["skfem", "mca"]
n = [2, 3]

[[group]]
id = "transient"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.01 }
solvers = ["skfem", "mca"]
n = [3, 4, 6]

[[group]]
id = "wp"
analysis = "work-precision"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.01 }
solvers = ["skfem"]
n = [3, 4]

[[claim]]
id = "steady-exact"
text = "skfem holds the steady line"
table = "steady-cells"
select = { solver = "skfem" }
per = "n"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9

[[calibration]]
id = "cal"
solver = "mca"
budget = 3
design_points = 3
starts = 0
tolerance = 0.5

[[calibration.parameter]]
name = "heat_cfl"
low = 0.3
high = 0.9

[[calibration.calibrate]]
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.01 }
n = 3
metric = "nodes.l2"
reference = "analytic"

[[calibration.validate]]
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.01 }
n = 4
metric = "nodes.linf"
reference = "analytic"
"""


def _tables(folder: Path) -> dict[str, str]:
    """Every CSV table of a study folder as text; of a calibration's summary, all but its counts of solver
    runs and cache hits (a rebuild from the cache runs nothing)."""
    out = {p.name: p.read_text() for p in sorted(folder.glob("*.csv"))}
    summary = pd.read_csv(folder / "cal-summary.csv").drop(columns=["solver_runs", "cache_hits"])
    return out | {"cal-summary.csv": summary.to_csv(index=False)}


def test_tables_and_calibrations_read_the_stored_errors(tmp_path, monkeypatch) -> None:
    """After the study ran, the reference and the compare step raise: rebuilding its tables (cells, levels and
    fits, work-precision, the calibration's trace and validation, the verdicts) from the cache gives the same
    files, so no table computes an error; the stored errors are those of the compare step."""
    (tmp_path / "s.toml").write_text(STUDY)
    out = tmp_path / "out"
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(out)]) == 0
    before = _tables(out / "stored-errors")
    levels = pd.read_csv(out / "stored-errors" / "transient-levels.csv")
    assert {"nodes.l2", "nodes.linf"} <= set(levels.columns) and levels["nodes.l2"].notna().all()
    assert pd.read_csv(out / "stored-errors" / "cal-validation.csv")["calibrated_error"].notna().all()

    def boom(*args, **kwargs):
        raise AssertionError("a table evaluated the reference")

    for name, module in list(sys.modules.items()):
        if name.startswith("pcverify") and getattr(module, "analytic", None) is heat.analytic:
            monkeypatch.setattr(module, "analytic", boom)
    monkeypatch.setattr(compare, "errors", boom)
    for p in (out / "stored-errors").glob("*.csv"):
        p.unlink()
    assert main(["study", str(tmp_path / "s.toml"), "--out", str(out)]) == 0  # every cell cached
    assert _tables(out / "stored-errors") == before
    stored = [json.loads(p.read_text())["result"] for p in (out / "cache").glob("*.json")]
    steady = [r for r in stored if r["scene_params"] == {} and r["solver"] == "skfem"]
    assert steady and all(set(r["errors"]["nodes"]) == {"l2", "linf", "reference"} for r in steady)


def test_the_cell_key_covers_the_compare_step_and_the_scene_family(tmp_path) -> None:
    """The key payload holds the compare step's fingerprint: its own module's (which follows its imports) and
    that of the family module defining the scene's spec and reference.  An edit of references/contact.py (a copy
    of the source) changes the key of a contact cell, one of references/heat.py that of a heat cell."""
    paper = load_study("continuum-heat").groups[0]
    payload, skip = cell_identity(paper.cells[0])
    assert skip is None and payload["compare"] == compare.fingerprint(paper.cells[0].scene)
    copy = installed_layout(REPO, tmp_path / "copy")
    probe = ("import json, pcverify.harness.judge.compare as c; from pcverify.harness.study.catalogue import "
             "make_scene as m; print(json.dumps([c.__file__, c.fingerprint(m('bar-heat-faces')), "
             "c.fingerprint(m('stick-slip'))]))")

    def fingerprint() -> tuple[str, str, str]:
        done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                              env={**os.environ, "PYTHONPATH": str(copy)}, cwd=tmp_path)
        return tuple(json.loads(done.stdout))

    where, heat, contact = fingerprint()
    assert where.startswith(str(copy)) and heat == compare.fingerprint(make_scene("bar-heat-faces"))
    family = copy / "pcverify" / "references" / "contact.py"
    family.write_text(family.read_text().replace("import math", "import math\nSHIFT = 1.0", 1))
    assert fingerprint()[2] != contact
    slab = copy / "pcverify" / "references" / "heat.py"
    slab.write_text(slab.read_text().replace("import math", "import math\nSHIFT = 1.0", 1))
    assert fingerprint()[1] != heat


def test_a_scene_without_a_reference_has_no_errors() -> None:
    """The paper's point constraints have no analytic solution: no errors, not a made-up one; a non-finite
    value (a run that is not ok) gives None, as in the JSON of a result."""
    paper, faces = make_scene("bar-heat-paper"), make_scene("bar-heat-faces")
    pts = faces.sample_sets(2)["nodes"]
    assert compare.errors(paper, {"nodes": {"points": pts, "values": [0.5] * len(pts)}}) == {}
    values = [math.nan] + [0.5] * (len(pts) - 1)
    got = compare.errors(faces, {"nodes": {"points": pts, "values": values}})
    assert got == {"nodes": {"l2": None, "linf": None, "reference": "analytic"}}
