"""One fair cost axis: the CPU seconds of a solve (set-up and kernel apart), the least of a timed cell's repeats
after a warm-up in one process, stamped with its timed pass (machine, time); a figure refuses to draw timings of
different passes side by side unless asked; a first solve in a process says it was cold."""

import json

import numpy as np
import pandas as pd

from pcverify.harness.cli import main
from pcverify.harness.report.figures import work_precision
from pcverify.harness.run.execution import solve_cost

STUDY = """
name = "cost"
[[group]]
id = "wp"
title = "steady faces: error against the CPU time of the solve"
analysis = "work-precision"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.1, dt = 0.05 }
solvers = ["fipy", "skfem"]
n = [2, 3]
[[group]]
id = "conv"
title = "the same, untimed"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.1, dt = 0.05 }
solvers = ["fipy"]
n = [4, 5]
"""


def test_the_cost_of_a_solve_split():
    """The kernel's share of the wall time, applied to the CPU time: on a machine where the solve waited half
    its wall time (4 s wall, 2 s CPU), a 3 s kernel is 1.5 CPU seconds."""
    assert solve_cost(2.0, 4.0, {"kernel_s": 3.0}) == {"cpu_s": 2.0, "kernel_s": 1.5, "setup_s": 0.5,
                                                        "kernel_wall_s": 3.0}
    assert solve_cost(2.0, 2.0, {"solve_s": 0.5, "assembly_s": 1.0})["kernel_s"] == 0.5
    assert solve_cost(2.0, 1.0, {"kernel_s": 3.0})["setup_s"] == 0.0  # a kernel clock past the wall: all kernel
    assert solve_cost(2.0, 2.0, {}) == {"cpu_s": 2.0, "kernel_s": None, "setup_s": None, "kernel_wall_s": None}


def test_timed_cells_on_one_cpu_axis(tmp_path):
    path = tmp_path / "cost.toml"
    path.write_text(STUDY)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--json"]) == 0
    folder = tmp_path / "out" / "cost"
    wp = pd.read_csv(folder / "wp-work-precision.csv")
    assert set(wp["solver"]) == {"fipy", "skfem"} and wp["run"].nunique() == 1 and wp["machine"].nunique() == 1
    assert (wp["timing"] == "serial after warm-up").all() and (wp["cpu_s"] > 0).all()
    assert (wp["repeats"] == 3).all()  # each solve far under 0.5 s: three solves, the least kept
    # both report a kernel (solve_s): kernel and set-up split the CPU time
    assert (wp["kernel_s"] > 0).all() and (wp["setup_s"] >= 0).all()
    assert np.allclose(wp["setup_s"] + wp["kernel_s"], wp["cpu_s"])
    assert not wp["cold"].any()  # the timed worker warmed up each solver first
    cache = tmp_path / "out" / "cache"
    timed = [json.loads(f.read_text())["result"] for f in cache.glob("*.json")]
    timed = [r for r in timed if isinstance(r.get("timing"), dict)]
    assert len(timed) == 4
    for r in timed:
        assert len(r["timing"]["cpu_s_samples"]) == 3 and r["cost"]["cpu_s"] == min(r["timing"]["cpu_s_samples"])
    figure = json.loads((folder / "wp.json").read_text())
    assert figure["axes"][0]["xlabel"] == "CPU time of the solve [s]"
    assert {s["label"] for s in figure["axes"][0]["series"]} == {"fipy", "skfem"}
    levels = pd.read_csv(folder / "conv-levels.csv")
    assert levels["cold"].tolist() in ([True, False], [False, False])  # a worker's first fipy solve, if it was


def test_timings_of_two_passes_are_not_drawn_together(tmp_path):
    rows = [{"solver": s, "cpu_s": c, "kernel_s": c / 2, "err.nodes.l2": e, "run": run, "machine": "m",
             "started": t} for s, c, e, run, t in [("a", 1.0, 0.1, "r1", "2026-11-20"), ("a", 2.0, 0.05, "r2",
                                                                                        "2026-11-26")]]
    df = pd.DataFrame(rows)
    assert work_precision(df, "err.nodes.l2", tmp_path / "wp", "mixed")
    refused = json.loads((tmp_path / "wp.json").read_text())
    assert all(not ax["series"] for ax in refused["axes"])
    assert work_precision(df, "err.nodes.l2", tmp_path / "wp2", "mixed", mix_runs=True)
    drawn = json.loads((tmp_path / "wp2.json").read_text())
    assert drawn["axes"][0]["series"][0]["x"] == [1.0, 2.0]


def test_two_studies_in_one_out_folder_each_time_their_cells_in_their_own_pass(tmp_path):
    """A timed cell is keyed by the study that times it: a second study sharing the first one's cells and cache
    times them again in its own pass, so both draw their work-precision figures (sharing them split a group's
    timings over two passes and the figure refused to draw)."""
    first = tmp_path / "cost.toml"
    first.write_text(STUDY)
    second = tmp_path / "cost2.toml"
    second.write_text(STUDY.replace('name = "cost"', 'name = "cost2"').replace("n = [2, 3]", "n = [3, 4]"))
    for path in (first, second):
        assert main(["study", str(path), "--out", str(tmp_path / "out"), "--json"]) == 0
    for name in ("cost", "cost2"):
        wp = pd.read_csv(tmp_path / "out" / name / "wp-work-precision.csv")
        assert wp["run"].nunique() == 1, wp[["solver", "n", "run"]]
        figure = json.loads((tmp_path / "out" / name / "wp.json").read_text())
        assert {s["label"] for s in figure["axes"][0]["series"]} == {"fipy", "skfem"}
