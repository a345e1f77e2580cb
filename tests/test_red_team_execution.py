"""Red team, running studies: the scheduler, a shared cache, shutdown, and results independent of --jobs.

- a malformed, empty, non-Dask or silent `--scheduler` is one line within seconds (no traceback, no huge
  allocation, no hang);
- a cache entry that is valid JSON with a valid checksum but not a cell result is recomputed; two
  processes running the same study at once compute no cell twice and write the serial run's tables;
- SIGTERM stops a study like Ctrl-C (message, exit 143, finished cells kept); after SIGTERM or SIGKILL of a
  --jobs 2 study no process of it is alive 10 s later; a dead writer's temporary file is removed.

That --jobs 1 and --jobs 2 give byte-identical tables (the shipped macromolecule study's groups among them) is
tests/test_determinism.py::test_shipped_tables_are_the_same_on_one_and_two_workers.

The command runs in this process (`run`) except where the process matters: signals, two processes sharing a
cache, and a Dask client (its event-loop thread and a possible hang stay out of the test process).
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import socket
import threading
import time
import uuid
from pathlib import Path

import pandas as pd
import pytest
from red_team import ENV, check_tally, cli, one_line_error, popen, processes_with, run, tally

SMALL = """
name = "small"
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["skfem", "fipy"]
n = [2, 3]
"""
SLOW = """
name = "slow"
[[group]]
id = "paper"
scene = "bar-heat-paper"
solvers = ["macromolecule"]
n = [2, 3]
solver_params = { t_end = 40.0 }
sweep = { seed = [1, 2, 3] }
"""


@pytest.fixture
def small(tmp_path) -> Path:
    (tmp_path / "small.toml").write_text(SMALL)
    return tmp_path


# ----------------------------------------------------------------------------- family 6: the scheduler
@pytest.mark.parametrize("address", ["", "localhost", "tcp://", "tcp://host", "http://127.0.0.1:8786", "8786",
                                     "tcp://127.0.0.1:8786/extra", "x" * 100_000])
def test_a_malformed_scheduler_address_is_one_line(small, address, capfd) -> None:
    t0 = time.perf_counter()
    line = one_line_error(run("study", "small.toml", "--out", "out", "--scheduler", address, cwd=small, capfd=capfd,
                              seconds=60))
    assert "scheduler=" in line and "allowed: the address of a running Dask scheduler" in line
    assert time.perf_counter() - t0 < 60 and not (small / "out" / "cache").exists()
    tally("scheduler", "rejected")


def _server(reply: bytes | None) -> tuple[socket.socket, int]:
    """A TCP endpoint on localhost that answers every connection with `reply` (or stays silent)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    held = []

    def serve() -> None:
        while True:
            try:
                conn, _ = srv.accept()
            except OSError:
                return
            held.append(conn)  # silent: keep it open, never answer
            if reply is not None:
                try:
                    conn.sendall(reply)
                except OSError:
                    pass

    threading.Thread(target=serve, daemon=True).start()
    return srv, srv.getsockname()[1]


@pytest.mark.parametrize("reply", [None, b"HTTP/1.1 200 OK\r\n\r\nhello", b"\xff" * 64, b"\x00" * 8 + b"\xff" * 56])
def test_a_scheduler_that_is_not_dask_is_one_line_within_seconds(small, reply) -> None:
    """A silent endpoint (accepts, never answers), an HTTP server and garbage that decodes as a huge
    message length: one line after a bounded wait, never a hang or a multi-EiB allocation."""
    pytest.importorskip("distributed")
    srv, port = _server(reply)  # a subprocess: a Dask client's threads, and a hang, stay out of the test process
    try:
        t0 = time.perf_counter()
        out = cli("study", "small.toml", "--out", "out", "--scheduler", f"tcp://127.0.0.1:{port}", cwd=small,
                  timeout=120)
        line = one_line_error(out)
        assert "scheduler='tcp://127.0.0.1:" in line and time.perf_counter() - t0 < 60
    finally:
        srv.close()
    tally("scheduler", "rejected")


# ----------------------------------------------------------------------------- family 8: a shared cache
def test_a_cache_entry_that_is_not_a_result_is_recomputed(small, capfd) -> None:
    done = run("study", "small.toml", "--out", "out", "--json", cwd=small, capfd=capfd)
    assert done.returncode == 0, done.stderr[-1500:]
    first = json.loads(done.stdout)[0]
    entry = sorted((small / "out" / "cache").glob("*.json"))[0]
    body = json.dumps({}, sort_keys=True)
    entry.write_text(json.dumps({"key": entry.stem, "sha256": hashlib.sha256(body.encode()).hexdigest(), "result": {}}))
    again = run("study", "small.toml", "--out", "out", "--json", cwd=small, capfd=capfd)
    summary = json.loads(again.stdout)[0]
    assert first["done"] == 4 and summary["corrupt"] == 1 and summary["done"] == 1 and summary["cached"] == 3
    assert "result has no status" in again.stderr
    tally("shared cache", "accepted")


def _tables(folder: Path) -> dict[str, pd.DataFrame]:
    out = {}
    for path in sorted(folder.glob("*.csv")):
        df = pd.read_csv(path)
        out[path.name] = df.drop(columns=[c for c in df.columns if c.endswith("_s") or c in ("wall_s", "timing")])
    return out


def test_two_copies_of_a_study_at_once_compute_no_cell_twice(tmp_path, capfd) -> None:
    """Two processes start the same 6-cell study on one --out at the same moment: together they compute
    each cell once (the other waits for it), both succeed, and the tables equal a serial run's (in process)."""
    (tmp_path / "slow.toml").write_text(SLOW)
    procs = [popen("study", "slow.toml", "--out", "shared", "--json", cwd=tmp_path) for _ in range(2)]
    outs = [p.communicate(timeout=600) for p in procs]
    assert [p.returncode for p in procs] == [0, 0], [o[1][-1500:] for o in outs]
    summaries = [json.loads(o[0])[0] for o in outs]
    assert sum(s["done"] for s in summaries) == 6, summaries
    assert all(s["done"] + s["cached"] == 6 for s in summaries)
    serial = run("study", "slow.toml", "--out", "serial", "--json", cwd=tmp_path, capfd=capfd)
    assert json.loads(serial.stdout)[0]["done"] == 6
    shared, alone = _tables(tmp_path / "shared" / "slow"), _tables(tmp_path / "serial" / "slow")
    assert shared.keys() == alone.keys()
    for name in alone:
        pd.testing.assert_frame_equal(shared[name], alone[name], check_exact=True)
    assert not list((tmp_path / "shared" / "cache").glob("*.lock"))
    tally("shared cache", "accepted")


# ----------------------------------------------------------------------------- family 9: shutdown
def _gone_within(marker: str, seconds: float) -> bool:
    deadline = time.time() + seconds
    while time.time() < deadline:
        if not processes_with(marker):
            return True
        time.sleep(0.25)
    return not processes_with(marker)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGKILL])
def test_a_killed_study_leaves_no_process_and_keeps_its_cells(tmp_path, sig, capfd) -> None:
    """A --jobs 2 study signalled mid-run (its main process only, as `kill PID` does): SIGTERM exits 143 with
    a message; after either signal every process of the study (workers, resource trackers) is gone
    within 10 s, and the cells finished before the signal are in the cache."""
    (tmp_path / "slow.toml").write_text(SLOW)
    marker = f"PCVERIFY_RED_TEAM_MARK={uuid.uuid4().hex}"
    env = {**ENV, marker.split("=")[0]: marker.split("=")[1]}
    proc = popen("study", "slow.toml", "--out", "out", "--jobs", "2", cwd=tmp_path, env=env)
    cache = tmp_path / "out" / "cache"
    deadline = time.time() + 300
    while time.time() < deadline and len(list(cache.glob("*.json"))) < 2:
        time.sleep(0.2)
    assert len(list(cache.glob("*.json"))) >= 2, "no cell finished"
    os.kill(proc.pid, sig)
    _, err = proc.communicate(timeout=60)
    if sig == signal.SIGTERM:
        assert proc.returncode == 128 + signal.SIGTERM
        assert "pcverify: terminated (finished cells are kept in the cache)" in err
    assert _gone_within(marker.split("=")[1], 10.0), processes_with(marker.split("=")[1])
    kept = len(list(cache.glob("*.json")))
    resumed = json.loads(run("study", "slow.toml", "--out", "out", "--json", cwd=tmp_path, capfd=capfd).stdout)[0]
    assert resumed["cached"] >= kept and resumed["done"] == 6 - resumed["cached"]
    tally("shutdown", "accepted")


def test_a_dead_writers_temporary_file_is_removed(small, capfd) -> None:
    cache = small / "out" / "cache"
    cache.mkdir(parents=True)
    stray = cache / ".0123456789abcdef0123.999999999.abc.tmp"  # pid 999999999 does not exist
    stray.write_text("half a")
    assert run("study", "small.toml", "--out", "out", cwd=small, capfd=capfd).returncode == 0
    assert not stray.exists()
    tally("shutdown", "accepted")


def test_zz_execution_tally() -> None:
    check_tally({"scheduler": 12, "shared cache": 2, "shutdown": 3})
