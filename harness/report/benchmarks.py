"""`pcverify bench`: the benchmarks of tests/bench run with pytest-benchmark, saved, and compared with the
newest saved run; a regression is one line naming each benchmark and by how much it regressed, exit 1."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

from pcverify.harness.report.write import benchmark_problem, warn
from pcverify.harness.run.files import read_json
from pcverify.harness.run.interrupt import check_interrupted
from pcverify.scene import SceneError

REGRESSION = re.compile(r"Field '(\w+)' has failed (\w+): ([-+0-9.eE]+) > ([-+0-9.eE]+)")


def bench_baseline(storage: Path) -> Path | None:
    """The newest saved benchmark run under `storage` (by run number) that is a pytest-benchmark save: the run
    `bench` compares with.  A file that is not (unreadable, invalid or too deeply nested JSON, another form) is
    skipped with a warning."""
    for file in sorted(storage.glob("*/*.json"), key=lambda f: (f.name, f.parent), reverse=True):
        doc, why = read_json(file)
        problem = why or benchmark_problem(doc)
        if problem:
            warn(f"{file} {problem}; not compared with")
            continue
        return file
    return None


def regression_line(regressions: list[tuple[str, str]], baseline: Path) -> str:
    """pytest-benchmark's regressions (benchmark, failed check) as one line: each benchmark, its field and by
    how much it regressed against the allowed limit, and the saved run compared with."""
    parts = []
    for name, check in regressions or [("(unnamed)", "performance has regressed")]:
        found = REGRESSION.search(check)
        if found and found[2].startswith("Percentage"):
            parts.append(f"{name.split(' (')[0]} {found[1]} +{float(found[3]):.1f} % (allowed: at most "
                         f"+{float(found[4]):g} %)")
        else:
            parts.append(f"{name.split(' (')[0]} {' '.join(check.split())}")
    return f"pcverify: benchmark regression against {baseline.name}: {'; '.join(parts)}"


class BenchmarkRegressions:
    """A pytest plugin that keeps pytest-benchmark's session, to read its regressions for the one-line message."""

    config: Any = None

    def pytest_configure(self, config: Any) -> None:
        self.config = config

    def found(self) -> list[tuple[str, str]]:
        session = getattr(self.config, "_benchmarksession", None)
        return [(str(name), str(check)) for name, check in getattr(session, "performance_regressions", None) or []]


def run_benchmarks(args: argparse.Namespace) -> int:
    """Run tests/bench with pytest-benchmark, save under --storage, compare with the previous saved run.  A
    regression is one line naming each benchmark and by how much it regressed, exit 1."""
    try:
        import pytest  # optional dependency (the test extra): only `pcverify bench` needs it
        from pytest_benchmark.session import PerformanceRegression  # the same optional dependency
    except ImportError as exc:
        raise SceneError(f"bench needs pytest and pytest-benchmark ({exc.name} is not installed); allowed: pip "
                         "install 'pcverify[test]'") from None

    storage = Path(args.storage).resolve()
    baseline = bench_baseline(storage)
    argv = [args.tests, "--benchmark-enable", "--benchmark-only", f"--benchmark-storage=file://{storage}",
            "--benchmark-autosave", "-p", "no:cacheprovider"]
    if baseline is not None:
        argv += [f"--benchmark-compare={baseline}", f"--benchmark-compare-fail=mean:{args.fail_percent:g}%"]
        print(f"comparing with {baseline.name}; failing on a mean regression beyond {args.fail_percent:g}%")
    else:
        print(f"no previous benchmark run under {storage}: this run becomes the baseline")
    plugin = BenchmarkRegressions()
    try:
        code = int(pytest.main(argv, plugins=[plugin]))
    except PerformanceRegression:
        sys.stdout.flush()
        print(regression_line(plugin.found(), baseline), file=sys.stderr)
        return 1
    check_interrupted()  # pytest turns a SIGTERM into its own exit code: stop like every other command
    return code
