"""A cached result is read back only while what its solve read is unchanged: a data file beside the solver's
module, and a module the solver imports by a name it computes (neither is in the source closure the cell key
hashes).  Before, editing either left the cached cells and their verdicts in place with the old numbers."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

from pcverify.harness.run.dependencies import file_entry, stale

PLUGIN = '''
import dataclasses
import importlib
import json
from pathlib import Path

from pcverify.solvers.continuum.skfem_heat import SkfemHeat


class ScaledHeat(SkfemHeat):
    """scikit-fem's heat solve with its volume mean scaled by a coefficient from data.json beside this module and
    shifted by the OFFSET of a module whose name is computed."""

    name = "scaled-heat"

    def solve(self, scene, resolution, samples=None, **params):
        sol = super().solve(scene, resolution, samples=samples, **params)
        scale = json.loads((Path(__file__).parent / "data.json").read_text())["scale"]
        offset = importlib.import_module("dyn" + "_" + "target").OFFSET
        summary = dict(sol.summary, volume_mean=sol.summary["volume_mean"] * scale + offset)
        return dataclasses.replace(sol, summary=summary)
'''

STUDY = '''
name = "depends"
plugins = ["scaled_heat"]

[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["scaled-heat"]
n = [2]
'''


def _study(folder: Path) -> dict:
    """The study as a user runs it: a process of its own (a process imports a module once)."""
    done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "study", str(folder / "depends.toml"),
                           "--out", str(folder / "out"), "--json"], capture_output=True, text=True, cwd=folder,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    (summary,) = json.loads(done.stdout)
    entry = json.loads(next((folder / "out" / "cache").glob("*.json")).read_text())["result"]
    return {"cached": summary["cached"], "done": summary["done"], "value": entry["summary"]["volume_mean"]}


def test_an_edited_data_file_or_computed_import_recomputes_the_cell(tmp_path) -> None:
    (tmp_path / "scaled_heat.py").write_text(PLUGIN)
    (tmp_path / "data.json").write_text('{"scale": 1.0}')
    (tmp_path / "dyn_target.py").write_text("OFFSET = 0.0\n")
    (tmp_path / "depends.toml").write_text(STUDY)
    first = _study(tmp_path)
    assert (first["cached"], first["done"]) == (0, 1)
    assert _study(tmp_path) == first | {"cached": 1, "done": 0}  # nothing changed: read back

    (tmp_path / "data.json").write_text('{"scale": 2.0}')
    second = _study(tmp_path)
    assert (second["cached"], second["done"]) == (0, 1)
    assert second["value"] == 2.0 * first["value"]

    (tmp_path / "dyn_target.py").write_text(textwrap.dedent("OFFSET = 1.0\n"))
    third = _study(tmp_path)
    assert (third["cached"], third["done"]) == (0, 1)
    assert third["value"] == second["value"] + 1.0
    assert _study(tmp_path)["cached"] == 1


def test_a_recorded_file_that_changed_or_went_is_stale(tmp_path) -> None:
    data = tmp_path / "data.json"
    data.write_text("1")
    depends = {"files": {str(data): file_entry(str(data))}, "modules": {}}
    assert stale(depends) == ""
    data.write_text("2")
    assert stale(depends) == f"the file {data} it read has changed"
    data.unlink()
    assert stale(depends) == f"the file {data} it read is gone"
    assert stale(None) == "" and stale({"files": {}, "modules": {}}) == ""
