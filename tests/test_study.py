"""Studies: cells are cached by content hash, corrupt entries are recomputed, reports are written."""

import json

import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute
from pcverify.harness.study.study import load_study

STUDY = """
name = "tiny"
title = "tiny study"
[[group]]
id = "faces"
title = "steady faces"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["fipy"]
n = [2, 3]
[[group]]
id = "patch"
title = "patch refinement"
analysis = "convergence"
scene = "bar-heat-patch"
scene_params = { rho = 0.003 }
solvers = ["fipy"]
n = [2]
refine = [2, 3, 4]
"""


@pytest.fixture
def study_file(tmp_path):
    path = tmp_path / "tiny.toml"
    path.write_text(STUDY)
    return path


def test_cache_resume_and_corruption(study_file, tmp_path):
    study = load_study(str(study_file))
    cache = Cache(tmp_path / "cache")
    first, counts = execute(study, cache, progress=False)
    assert counts == {"cells": 5, "cached": 0, "done": 5, "failed": 0, "corrupt": 0, "statuses": {"ok": 5}}
    again, counts = execute(study, cache, progress=False)
    assert counts["cached"] == 5 and counts["done"] == 0
    assert [r["summary"] for r in again] == [r["summary"] for r in first]
    # corrupt one entry (truncated write) and tamper with another (checksum): both detected and recomputed
    entries = sorted(cache.root.glob("*.json"))
    entries[0].write_text(entries[0].read_text()[:50])
    doc = json.loads(entries[1].read_text())
    doc["result"]["summary"]["bulk_median"] = 0.123
    entries[1].write_text(json.dumps(doc))
    fixed, counts = execute(study, cache, progress=False)
    assert counts["corrupt"] == 2 and counts["done"] == 2 and counts["cached"] == 3
    assert [r["summary"] for r in fixed] == [r["summary"] for r in first]


def test_study_cli_writes_tables_and_index(study_file, tmp_path, capsys):
    out = tmp_path / "reports"
    assert main(["study", str(study_file), "--out", str(out)]) == 0
    assert (out / "index.html").exists()
    fits = pd.read_csv(out / "tiny" / "patch-fits.csv")
    assert set(fits["quantity"]) == {"volume_mean", "bulk_median"}
    cells = pd.read_csv(out / "tiny" / "faces-cells.csv")
    # steady faces: the analytic error columns are present and at round-off
    assert cells["err.nodes.linf"].max() < 1e-9
    html = (out / "index.html").read_text()
    assert "data:image/png;base64," in html and "Provenance" in html
    capsys.readouterr()
    assert main(["study", str(study_file), "--out", str(out), "--dry-run"]) == 0
    assert capsys.readouterr().out.count("cached") == 5
    assert main(["report", "--out", str(out), "--json"]) == 0


@pytest.mark.parametrize(
    "text, word",
    [
        ("name='x'\n[[group]]\nscene='bar-heat-nope'\nsolvers=['fipy']\n", "scene="),
        ("name='x'\n[[group]]\nscene='bar-heat-paper'\nanalysis='magic'\nsolvers=['fipy']\n", "analysis="),
        ("name='x'\n[[group]]\nscene='bar-heat-patch'\nscene_params={rho=-1}\nsolvers=['fipy']\n", "rho="),
        ("name='x'\n[[group\n", "not valid TOML"),
        ("name='x'\n", "no [[group]]"),
    ],
)
def test_bad_study_files_fail_with_one_line(tmp_path, text, word, capsys):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    assert main(["study", str(path), "--out", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert word in err and "Traceback" not in err


def _summaries(results):
    return [(r["group"], r["solver"], r["n"], r["refine"], json.dumps(r["summary"], sort_keys=True)) for r in results]


def test_parallel_and_dask_equal_serial(study_file, tmp_path):
    """Cells computed by worker processes or a Dask cluster equal the serial ones bit for bit, in cell order."""
    distributed = pytest.importorskip("distributed")
    study = load_study(str(study_file))
    serial, _ = execute(study, Cache(tmp_path / "serial"), progress=False)
    parallel, counts = execute(study, Cache(tmp_path / "workers"), jobs=2, progress=False)
    assert counts["done"] == 5 and _summaries(parallel) == _summaries(serial)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as lc:
        dask, counts = execute(study, Cache(tmp_path / "dask"), progress=False, scheduler=lc.scheduler_address)
    assert counts["done"] == 5 and _summaries(dask) == _summaries(serial)


def test_unreachable_scheduler_is_a_clear_error(study_file, tmp_path, capsys):
    pytest.importorskip("distributed")
    args = ["study", str(study_file), "--out", str(tmp_path / "r"), "--scheduler", "tcp://127.0.0.1:9"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "scheduler=" in err and "not reachable" in err and "Traceback" not in err


def test_timing_groups_run_serially_after_warm_up(tmp_path, monkeypatch):
    """A timing group's cells are keyed apart from the same cells elsewhere and run after a warm-up solve; the
    same cells of another group are not solved again: they take the timed results."""
    import pcverify.harness.run.execution as st

    path = tmp_path / "timed.toml"
    path.write_text(STUDY + '[[group]]\nid = "cost"\nanalysis = "timing"\nscene = "bar-heat-faces"\n'
                    'solvers = ["fipy"]\nn = [2, 3]\n')
    study = load_study(str(path))
    calls = []
    real = st.run_cell
    monkeypatch.setattr(st, "run_cell", lambda cell: calls.append((cell.group, cell.n, cell.serial)) or real(cell))
    results, counts = execute(study, Cache(tmp_path / "c"), jobs=2, progress=False)
    assert (counts["done"], counts["cached"]) == (5, 2)  # fipy n = 2, 3 of the faces group: the timed solves
    # in-process calls: the warm-up (cheapest fipy cell) and then the two timed cells, last, three solves each
    # (each far under REPEAT_BELOW_S; the least CPU time is kept)
    assert calls[-7:] == [("cost", 2, True)] * 4 + [("cost", 3, True)] * 3
    timed = [r for r in results if r["group"] == "cost"]
    assert all(r["timing"]["kind"] == "serial after warm-up" and r["timing"]["repeats"] == 3 for r in timed)
    assert len({r["timing"]["run"] for r in timed}) == 1


def test_a_cell_cached_by_another_group_belongs_to_this_group(tmp_path):
    """Two groups (or studies) with the same solve share one cache entry; each sees it as its own cell."""
    path = tmp_path / "twice.toml"
    path.write_text(STUDY + '[[group]]\nid = "again"\nanalysis = "table"\nscene = "bar-heat-faces"\n'
                    'solvers = ["fipy"]\nn = [2, 3]\n')
    study = load_study(str(path))
    results, counts = execute(study, Cache(tmp_path / "c"), progress=False)
    assert counts["done"] == 5 and counts["cached"] == 2  # the faces cells are computed once
    again = [r for r in results if r["group"] == "again"]
    faces = [r for r in results if r["group"] == "faces"]
    assert [r["n"] for r in again] == [2, 3] and [r["summary"] for r in again] == [r["summary"] for r in faces]
