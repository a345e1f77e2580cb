"""A figure of any metric against any swept parameter (the group's figures = ["parameter"], figure_x, figure_y):
one panel per metric, one line per solver and setting of the other varying parameters."""

import json

import pytest

from pcverify.harness.cli import main

STUDY = """
name = "sweepfig"
[[group]]
id = "cn"
title = "FiPy Crank-Nicolson on the transient faces: the error against its implicit-Euler start"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.2, dt = 0.05 }
solvers = ["fipy"]
n = [3, 4]
solver_params = { scheme = "crank-nicolson" }
sweep = { rannacher_steps = [0, 2, 4] }
figures = ["parameter"]
figure_x = "rannacher_steps"
figure_y = ["err.nodes.l2", "err.nodes.linf", "volume_mean"]
"""


def test_metrics_against_a_swept_parameter(tmp_path):
    path = tmp_path / "sweepfig.toml"
    path.write_text(STUDY)
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--json"]) == 0
    folder = tmp_path / "out" / "sweepfig"
    figure = json.loads((folder / "cn-rannacher_steps.json").read_text())
    assert [a["ylabel"] for a in figure["axes"]] == ["err.nodes.l2", "err.nodes.linf", "volume_mean"]
    for axes in figure["axes"]:
        assert axes["xlabel"] == "rannacher_steps" and axes["xscale"] == "linear"  # 0 is on the axis
        assert sorted(s["label"] for s in axes["series"]) == ["fipy n=3", "fipy n=4"]
        assert all(s["x"] == [0, 2, 4] for s in axes["series"])
    manifest = json.loads((folder / "manifest.json").read_text())
    assert "cn-rannacher_steps.png" in manifest["sections"][0]["figures"]


@pytest.mark.parametrize("line, word", [
    ('figure_x = "rannacher_steps"\n', 'figures = "parameter" needs figure_x'),
])
def test_a_parameter_figure_needs_its_axis(tmp_path, capsys, line, word):
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace(line, ""))
    assert main(["study", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert word in err and len(err.strip().splitlines()) == 1
