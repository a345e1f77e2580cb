"""Reports written at once after every study has computed: one forked writer per report gives the same files as
one writer for all, and an interrupted run still writes the reports of the studies that finished."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

import pcverify.harness.report.batch as batch
import pcverify.harness.report.studies as studies
from pcverify.harness.cli import main


def _study(tmp_path: Path, name: str, n: list[int]) -> Path:
    path = tmp_path / f"{name}.toml"
    path.write_text(f'name = "{name}"\n[[group]]\nid = "faces"\nanalysis = "convergence"\nscene = "bar-heat-faces"\n'
                    f'solvers = ["skfem", "fipy"]\nn = {n}\n'
                    '[[claim]]\nid = "line"\ntext = "exact"\ntable = "faces-levels"\nper = "solver"\n'
                    'metric = "nodes.linf"\nreference = "analytic"\ntolerance = 1e-9\n')
    return path


def _files(folder: Path) -> dict[str, bytes]:
    # the manifest names the command that ran it (its --out differs): compared apart
    return {p.name: p.read_bytes() for p in folder.iterdir()
            if p.suffix in (".csv", ".json") and p.name != "manifest.json"}


def test_two_studies_written_by_two_processes_equal_those_written_by_one(tmp_path, capsys):
    paths = [_study(tmp_path, "alpha", [2, 3]), _study(tmp_path, "beta", [2, 3, 4])]
    cache = str(tmp_path / "cache")
    for jobs, out in (("1", "one"), ("2", "two")):
        for path in paths:  # one study per run with --jobs 1, both cached and written at once with --jobs 2
            assert main(["study", str(path), "--out", str(tmp_path / out), "--cache", cache, "--jobs", jobs]) == 0
    for name in ("alpha", "beta"):
        one, two = _files(tmp_path / "one" / name), _files(tmp_path / "two" / name)
        assert set(one) == set(two) and "verdicts.json" in one and "faces-levels.csv" in one
        assert one == two


def test_an_interrupted_run_writes_the_reports_of_the_studies_that_finished(tmp_path, capsys, monkeypatch):
    """Two studies run as `default` runs the shipped ones: the second is interrupted while computing, the first
    still gets its report."""
    paths = [_study(tmp_path, "alpha", [2]), _study(tmp_path, "beta", [2])]
    monkeypatch.setattr(studies, "study_files", lambda: {str(p): p for p in paths})
    real = studies.execute

    def execute(study, *args, **kwargs):
        if study.name == "beta":
            raise KeyboardInterrupt
        return real(study, *args, **kwargs)

    monkeypatch.setattr(studies, "execute", execute)
    assert main(["study", "default", "--out", str(tmp_path / "out"), "--jobs", "2"]) == 130
    err = capsys.readouterr().err
    assert "writing the reports of the 1 studies that finished" in err
    assert (tmp_path / "out" / "alpha" / "verdicts.json").is_file()
    assert not (tmp_path / "out" / "beta").exists()


@pytest.mark.parametrize("jobs", ["1", "2"])
def test_a_report_that_cannot_be_written_is_one_error_line(tmp_path, capsys, monkeypatch, jobs):
    """A file where beta's report folder goes: written in a forked writer or here, the error is one line."""
    paths = [_study(tmp_path, "alpha", [2]), _study(tmp_path, "beta", [2])]
    monkeypatch.setattr(studies, "study_files", lambda: {str(p): p for p in paths})
    out = tmp_path / "out"
    out.mkdir()
    (out / "beta").write_text("a file where the report folder goes")
    code = main(["study", "default", "--out", str(out), "--jobs", jobs])
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err and "beta" in err.strip().splitlines()[-1]


def test_a_writer_that_dies_leaves_its_report_to_this_process(tmp_path, monkeypatch):
    """A forked writer killed before it writes (here: it exits at once for beta) never leaves the run waiting:
    beta's report is written by the process that ran the studies, alpha's by its writer."""
    paths = [_study(tmp_path, "alpha", [2]), _study(tmp_path, "beta", [2])]
    monkeypatch.setattr(studies, "study_files", lambda: {str(p): p for p in paths})
    parent, write = os.getpid(), batch._write

    def dies_in_a_writer(job, out):
        if os.getpid() != parent and job.study.name == "beta":
            os._exit(9)
        return write(job, out)

    monkeypatch.setattr(batch, "_write", dies_in_a_writer)
    assert main(["study", "default", "--out", str(tmp_path / "out"), "--jobs", "2"]) == 0
    for name in ("alpha", "beta"):
        assert (tmp_path / "out" / name / "verdicts.json").is_file()
