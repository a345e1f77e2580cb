"""A Dask scheduler and worker killed in the middle of a study: the cells they held fail with the reason, the
report is written, and stderr says so in lines of pcverify's own, without distributed's ERROR log records and
their chained tracebacks."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

pytest.importorskip("distributed")

ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
DASK = str(Path(sys.executable).with_name("dask"))

PLUGIN = '''
import time

from pcverify.solvers.continuum.skfem_heat import SkfemHeat


class SlowHeat(SkfemHeat):
    """scikit-fem's heat solve after a pause: a study long enough to lose its cluster in the middle."""

    name = "slow-heat"

    def solve(self, scene, resolution, samples=None, **params):
        time.sleep(1.5)
        return super().solve(scene, resolution, samples=samples, **params)
'''


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_lost_cluster_fails_its_cells_in_one_line_each(tmp_path) -> None:
    (tmp_path / "slow_heat.py").write_text(PLUGIN)
    (tmp_path / "s.toml").write_text(textwrap.dedent('''
        name = "lost"
        plugins = ["slow_heat"]

        [[group]]
        id = "faces"
        scene = "bar-heat-faces"
        solvers = ["slow-heat"]
        n = [2, 3, 4, 5, 6, 7, 8, 9]
    '''))
    address = f"tcp://127.0.0.1:{_free_port()}"
    env = {**ENV, "PYTHONPATH": os.pathsep.join([str(tmp_path), ENV.get("PYTHONPATH", "")])}
    scheduler = subprocess.Popen([DASK, "scheduler", "--host", "127.0.0.1", "--port", address.rsplit(":", 1)[1],
                                  "--no-dashboard"], env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                 start_new_session=True)
    worker = subprocess.Popen([DASK, "worker", address, "--nworkers", "1", "--nthreads", "1", "--no-dashboard"],
                              env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)
    try:
        time.sleep(8)  # the cluster up
        study = subprocess.Popen([sys.executable, "-m", "pcverify.harness.cli", "study", "s.toml", "--out", "out",
                                  "--scheduler", address], cwd=tmp_path, env=env, stdout=subprocess.PIPE,
                                 stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and len(list((tmp_path / "out" / "cache").glob("*.json"))) < 2:
            time.sleep(0.2)
        for proc in (worker, scheduler):
            os.killpg(proc.pid, signal.SIGKILL)
        out, err = study.communicate(timeout=240)
    finally:
        for proc in (worker, scheduler):
            proc.kill() if proc.poll() is None else None
    assert study.returncode in (0, 1), err[-3000:]
    assert "Traceback" not in err and "ERROR" not in err and "distributed." not in err, err[-3000:]
    assert (tmp_path / "out" / "lost" / "manifest.json").is_file()
    cells = (tmp_path / "out" / "lost" / "cells.csv").read_text()
    assert "its Dask task failed" in cells  # the cells the cluster held, each with the reason
