"""`pcverify bench` outside a checkout: the benchmarks (tests/bench) come with a checkout of the project, not with
the installed package, so without them the command says in one line what it needs (exit 2), runs nothing and
writes nothing; so does a missing pytest-benchmark."""

from __future__ import annotations

import sys

import pytest

from pcverify.harness.cli import main


def _one_error_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith("pcverify: error: "), lines[0]
    return lines[0]


@pytest.mark.parametrize("argv", [["bench"], ["bench", "--tests", "no/such/folder"]])
def test_bench_without_its_benchmarks_says_what_it_needs(argv: list[str], tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)  # an installed pcverify, run outside a checkout: no tests/bench here
    assert main(argv) == 2
    line = _one_error_line(capsys)
    assert "a checkout of the project" in line and "--tests PATH" in line, line
    assert f"--tests {argv[-1] if len(argv) > 1 else 'tests/bench'}: no such folder" in line, line
    assert not list(tmp_path.iterdir())  # nothing run, nothing saved


def test_bench_without_pytest_benchmark_says_what_to_install(tmp_path, monkeypatch, capsys) -> None:
    (tmp_path / "tests" / "bench").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setitem(sys.modules, "pytest_benchmark.session", None)  # as if pytest-benchmark were not installed
    assert main(["bench"]) == 2
    assert "pip install 'pcverify[test]'" in _one_error_line(capsys)
