"""Fault tolerance of studies: SIGKILL and SIGINT in the middle of a study, corrupted cache entries of
every kind, a full or read-only cache folder, an output folder that cannot be written.  In each case:
a clear one-line message, no finished cell lost, and a rerun that resumes and ends with the same
tables as an uninterrupted run.

The kill tests run the real console script as a subprocess on a user study file (FiPy cells of a
fraction of a second each, so the kill lands mid-study; reference runs and reruns go through main()
in-process); the write-failure tests run in-process on cheap skfem cells.
As root (CI containers) chmod cannot make a folder read-only, so write failures are injected at the
system call (errno ENOSPC / EROFS) or provoked with a path whose parent is a regular file.
"""

from __future__ import annotations

import errno
import json
import os
import select
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.run import cache as cache_module
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import execute
from pcverify.harness.study.study import load_study

SLOW_STUDY = """name = "killme"
title = "FiPy cells of a fraction of a second each"
[[group]]
id = "faces"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["fipy"]
n = [5, 6, 7, 8, 9, 10, 11]
"""
FAST_STUDY = """name = "quick"
title = "cheap continuum cells"
[[group]]
id = "faces"
analysis = "table"
scene = "bar-heat-faces"
solvers = ["skfem"]
n = [2, 3, 4, 5, 6]
"""
CELLS = 7
ENV = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
EXE = shutil.which("pcverify") or str(Path(sys.executable).with_name("pcverify"))
CLOCK_COLUMNS = ("wall", "elapsed", "timing", "kernel_s")  # wall-clock columns differ between runs by nature


def _entries(folder: Path) -> dict[str, tuple[int, bytes]]:
    """Cache entries: name -> (mtime_ns, bytes); temporary files of unfinished writes left out."""
    return {p.name: (p.stat().st_mtime_ns, p.read_bytes()) for p in folder.glob("*.json")}


def _tables(folder: Path) -> dict[str, pd.DataFrame]:
    out = {}
    for path in sorted(folder.glob("*.csv")):
        try:
            df = pd.read_csv(path)
        except pd.errors.EmptyDataError:
            df = pd.DataFrame()
        out[path.name] = df[[c for c in df.columns if not (any(w in c for w in CLOCK_COLUMNS) or c.endswith("_s"))]]
    return out


def _assert_same_tables(a: Path, b: Path) -> None:
    ta, tb = _tables(a), _tables(b)
    assert ta.keys() == tb.keys() and ta
    for name in ta:
        pd.testing.assert_frame_equal(ta[name], tb[name], check_exact=True, obj=name)


def _start(study: Path, cache: Path, out: Path, jobs: int = 1) -> subprocess.Popen:
    """The console script in its own process group (Ctrl-C in a terminal signals the whole group)."""
    return subprocess.Popen([EXE, "study", str(study), "--cache", str(cache), "--out", str(out), "--json",
                             "--jobs", str(jobs)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
                            start_new_session=True, preexec_fn=_default_sigint)


def _default_sigint() -> None:
    """Ctrl-C as in a terminal even when this test runs in the background (where SIGINT is inherited as
    ignored and Python, rightly, then keeps ignoring it)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _run(study: Path, cache: Path, out: Path) -> dict:
    """An uninterrupted run (or a rerun) in-process: its JSON summary."""
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["study", str(study), "--cache", str(cache), "--out", str(out), "--json"]) == 0
    return json.loads(buf.getvalue().strip().splitlines()[-1])[0]


def _wait_for_entries(proc: subprocess.Popen, cache: Path, count: int, timeout: float = 300.0) -> None:
    t0 = time.monotonic()
    while len(list(cache.glob("*.json"))) < count:
        assert proc.poll() is None, f"the study ended before {count} cells were cached: {proc.stderr.read()}"
        assert time.monotonic() - t0 < timeout
        time.sleep(0.02)


@pytest.fixture(scope="module")
def slow_study(tmp_path_factory) -> tuple[Path, Path]:
    """The slow study file and its uninterrupted run's report folder (the reference tables)."""
    root = tmp_path_factory.mktemp("slow")
    path = root / "killme.toml"
    path.write_text(SLOW_STUDY)
    counts = _run(path, root / "ref-cache", root / "ref-out")
    assert counts["done"] == CELLS and counts["failed"] == 0
    return path, root / "ref-out" / "killme"


def test_sigkill_then_resume(slow_study, tmp_path) -> None:
    """Issue 5: kill -9 a running study once some cells are cached, rerun it: no finished cell is
    recomputed (same bytes, same mtimes, the runner counts them as cached) and the final tables equal
    those of an uninterrupted run."""
    path, reference = slow_study
    cache, out = tmp_path / "cache", tmp_path / "out"
    proc = _start(path, cache, out)
    _wait_for_entries(proc, cache, 2)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    before = _entries(cache)
    assert 2 <= len(before) < CELLS, "the kill must land mid-study"
    counts = _run(path, cache, out)
    assert counts["cached"] == len(before) and counts["done"] == CELLS - len(before) and counts["corrupt"] == 0
    after = _entries(cache)
    assert all(after[name] == before[name] for name in before)  # not recomputed, not rewritten
    _assert_same_tables(out / "killme", reference)


@pytest.mark.parametrize("jobs", [1, 2])
def test_sigint_stops_with_a_message_and_resumes(jobs, slow_study, tmp_path) -> None:
    """Ctrl-C (SIGINT to the process group, worker processes included): exit code 130, one line saying
    finished cells are kept, no traceback, no worker left; every entry on disk is valid and the rerun
    picks up exactly those."""
    path, reference = slow_study
    cache, out = tmp_path / "cache", tmp_path / "out"
    proc = _start(path, cache, out, jobs)
    _wait_for_entries(proc, cache, 1)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    assert err.strip().splitlines()[-1] == "pcverify: interrupted (finished cells are kept in the cache)"
    before = _entries(cache)
    assert 1 <= len(before) < CELLS
    assert all(Cache(cache).load(name[:-5])[1] == "hit" for name in before)
    counts = _run(path, cache, out)
    assert counts["cached"] == len(before) and counts["done"] == CELLS - len(before) and counts["corrupt"] == 0
    _assert_same_tables(out / "killme", reference)


# ----------------------------------------------------------------------------- in-process, cheap cells
@pytest.fixture
def fast_study(tmp_path) -> Path:
    path = tmp_path / "quick.toml"
    path.write_text(FAST_STUDY)
    return path


@pytest.fixture(scope="module")
def fast_reference(tmp_path_factory) -> list[dict]:
    root = tmp_path_factory.mktemp("fastref")
    path = root / "quick.toml"
    path.write_text(FAST_STUDY)
    results, counts = execute(load_study(str(path)), Cache(root / "cache"), progress=False)
    assert counts["done"] == 5
    return results


def _physics(results: list[dict]) -> list:
    return [(r["n"], r["status"], r["summary"], r["samples"]) for r in results]


CORRUPTIONS = {
    "empty file": lambda p, other: p.write_bytes(b""),
    "binary garbage": lambda p, other: p.write_bytes(os.urandom(64)),
    "JSON of the wrong shape": lambda p, other: p.write_text("[1, 2, 3]"),
    "result not a table": lambda p, other: p.write_text(json.dumps({"key": p.stem, "sha256": "0", "result": "x"})),
    "another cell's entry": lambda p, other: p.write_bytes(other.read_bytes()),
    "truncated": lambda p, other: p.write_bytes(p.read_bytes()[: len(p.read_bytes()) // 2]),
}


def test_corrupt_entries_of_every_kind_are_recomputed(fast_study, fast_reference, tmp_path, capsys) -> None:
    """Each kind of damage is detected (counted, reported with the cell), recomputed, and the results
    equal the reference; a stray temporary file of a killed write is ignored."""
    study = load_study(str(fast_study))
    cache = Cache(tmp_path / "cache")
    execute(study, cache, progress=False)
    paths = sorted(cache.root.glob("*.json"))
    for (kind, damage), path in zip(CORRUPTIONS.items(), paths * 2, strict=False):
        other = paths[(paths.index(path) + 1) % len(paths)]
        clean = path.read_bytes()
        damage(path, other)
        (cache.root / f".{path.stem}.abc123.tmp").write_text('{"key": "half a wri')
        results, counts = execute(study, cache, progress=False)
        assert counts["corrupt"] == 1 and counts["done"] == 1 and counts["cached"] == 4, kind
        assert _physics(results) == _physics(fast_reference), kind
        assert json.loads(path.read_bytes())["result"]["summary"] == json.loads(clean)["result"]["summary"]


def _failing_after(k: int, code: int):
    """os.fsync that works k times, then fails like a full (ENOSPC) or read-only (EROFS) disk."""
    calls = {"n": 0}
    real = os.fsync

    def fsync(fd: int) -> None:
        calls["n"] += 1
        if calls["n"] > k:
            raise OSError(code, os.strerror(code))
        real(fd)

    return fsync


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EROFS])
def test_failed_cache_write_stops_cleanly_and_resumes(code, fast_study, fast_reference, tmp_path, monkeypatch,
                                                      capsys) -> None:
    """The third write fails: exit 2 with one line naming the entry and the cause, the two finished
    entries intact, no temporary file left behind; once the disk is fixed the rerun resumes from them."""
    cache, out = tmp_path / "cache", tmp_path / "out"
    argv = ["study", str(fast_study), "--cache", str(cache), "--out", str(out), "--json"]
    monkeypatch.setattr(cache_module.os, "fsync", _failing_after(2, code))
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert "cannot write cache entry" in err and os.strerror(code) in err and "rerun" in err
    assert len(list(cache.glob("*.json"))) == 2 and not list(cache.glob(".*.tmp"))
    assert all(Cache(cache).load(p.stem)[1] == "hit" for p in cache.glob("*.json"))
    monkeypatch.undo()
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])[0]
    assert summary["cached"] == 2 and summary["done"] == 3
    results, counts = execute(load_study(str(fast_study)), Cache(cache), progress=False)
    assert counts["cached"] == 5 and _physics(results) == _physics(fast_reference)


def test_unwritable_output_folder_keeps_the_cells(fast_study, tmp_path, capsys) -> None:
    """--out under a regular file: the cells are solved and cached (separate --cache), the report
    write fails in one line naming the path, and a rerun with a good --out only reads the cache."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    cache = tmp_path / "cache"
    code = main(["study", str(fast_study), "--cache", str(cache), "--out", str(blocker / "reports"), "--json"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and "Traceback" not in err
    assert str(blocker) in err and "rerun" in err
    assert len(list(cache.glob("*.json"))) == 5
    assert main(["study", str(fast_study), "--cache", str(cache), "--out", str(tmp_path / "out"), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])[0]
    assert summary["cached"] == 5 and summary["done"] == 0
    assert (tmp_path / "out" / "quick" / "cells.csv").exists()


def test_swallowed_ctrl_c_still_stops_the_study(fast_study, tmp_path, monkeypatch) -> None:
    """FiPy evaluates variables under bare `except:`, so a KeyboardInterrupt raised inside it is lost
    (seen as a flaky Ctrl-C: the study ran to the end).  The runner remembers the SIGINT and stops
    after the cell in progress, which is stored: here the second cell swallows the interrupt."""
    import pcverify.harness.run.execution as st
    from pcverify.harness.run.interrupt import remember_sigint

    real = st.run_cell
    calls = {"n": 0}

    def swallowing(cell):
        calls["n"] += 1
        if calls["n"] == 2:
            try:
                os.kill(os.getpid(), signal.SIGINT)
                time.sleep(1.0)
            except KeyboardInterrupt:  # what a bare `except:` in a library does
                pass
        return real(cell)

    monkeypatch.setattr(st, "run_cell", swallowing)
    cache = Cache(tmp_path / "cache")
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)  # as in a terminal, also in background
    try:
        with pytest.raises(KeyboardInterrupt), remember_sigint():
            execute(load_study(str(fast_study)), cache, progress=False)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert calls["n"] == 2 and len(list(cache.root.glob("*.json"))) == 2
    assert all(cache.load(p.stem)[1] == "hit" for p in cache.root.glob("*.json"))


def _dead_pid() -> int:
    """The pid of a process that has exited (reaped)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_stale_takeover_decision_does_not_remove_a_live_lock(tmp_path) -> None:
    """Process B found the holder of a cell's lock dead; before B removed it, process A took it over.  B's
    removal decides again under the takeover guard and leaves A's lock: only A computes the cell."""
    key = "k" * 16
    (tmp_path / f"{key}.lock").write_text(json.dumps({"pid": _dead_pid(), "host": cache_module.HOST}))
    a, b = Cache(tmp_path), Cache(tmp_path)
    assert a.holder(key) is None
    assert a.try_lock(key)  # takes over the dead holder's lock
    b._remove_if_dead(key)  # B acting on its earlier, now stale, observation
    assert a.holder(key) == (os.getpid(), cache_module.HOST)
    assert not b.try_lock(key)


def _race_for_the_lock(root: Path, key: str, processes: int, seconds: float = 120.0) -> list[int]:
    """Fork `processes` children that each try once to take `key`'s lock: 0 if it got it, 1 if not, 3 if trying
    failed.  They start together (a pipe they all read, released at once when it closes) and each stays alive
    until all have answered (a holder that ended before a slow starter tried would be a dead holder again,
    rightly taken over), so the outcome does not depend on how busy the machine is."""
    go_r, go_w = os.pipe()
    answers_r, answers_w = os.pipe()  # a byte from each child: its code
    stay_r, stay_w = os.pipe()  # closed by this process once all have answered: they may end
    parent_ends, children = [go_r, go_w, answers_r, answers_w, stay_r, stay_w], []
    try:
        for _ in range(processes):
            pid = os.fork()
            if pid == 0:  # child: wait for the common start, try once, stay alive while the others try
                code = 3
                try:
                    try:
                        for fd in (go_w, answers_r, stay_w):
                            os.close(fd)
                        os.read(go_r, 1)
                        code = 0 if Cache(root).try_lock(key) else 1
                    finally:
                        os.write(answers_w, bytes([code]))
                        os.read(stay_r, 1)
                finally:
                    os._exit(code)
            children.append(pid)
        for fd in (go_r, answers_w, stay_r, go_w):  # go_w last: the start
            os.close(fd)
            parent_ends.remove(fd)
        answers, deadline = b"", time.monotonic() + seconds
        while len(answers) < processes:
            assert time.monotonic() < deadline, f"{len(answers)} of {processes} processes tried in {seconds:g} s"
            if select.select([answers_r], [], [], 1.0)[0]:
                chunk = os.read(answers_r, processes)
                assert chunk, "a process ended without trying"
                answers += chunk
    finally:
        for fd in parent_ends:  # every child starts (if it had not) and ends, also when this process failed
            os.close(fd)
        codes = [os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) for pid in children]
    return codes


def test_processes_racing_for_a_dead_holders_lock_take_it_once(tmp_path) -> None:
    """Eight forked processes start together on a cell whose lock's holder has died, 10 rounds: in every
    round exactly one of them gets the lock (without the guard two could, each removing the other's)."""
    key = "k" * 16
    for _ in range(10):
        (tmp_path / f"{key}.lock").write_text(json.dumps({"pid": _dead_pid(), "host": cache_module.HOST}))
        codes = _race_for_the_lock(tmp_path, key, 8)
        assert sorted(codes) == [0] + [1] * 7, codes
        (tmp_path / f"{key}.lock").unlink()
