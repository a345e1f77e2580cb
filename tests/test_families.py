"""Scene families: every shipped scene has one home in pcverify.references with its reference and scalar contract;
the harness names no scene; the study targets that are properties of a scene are its reference's scalars; a
plugin's scene is compared with the plugin's own reference and its module is part of the cell key."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pcverify import references
from pcverify.harness.judge import compare
from pcverify.harness.report import figures
from pcverify.harness.study import catalogue
from pcverify.harness.study.catalogue import get_spec, make_scene, register_scene
from pcverify.harness.study.study import load_study
from pcverify.references.heat import Slab

REPO = Path(__file__).resolve().parent.parent
PLUGIN = REPO / "examples" / "fd-heat-plugin"
NAMES = [spec.name for spec in references.SCENES]


def test_each_shipped_scene_has_one_family_and_the_catalogue_holds_them_all() -> None:
    assert len(NAMES) == len(set(NAMES)) and list(catalogue.CATALOGUE) == NAMES
    for spec in references.SCENES:
        assert spec.build.__module__.rpartition(".")[2] in ("heat", "lattice", "elastic", "contact"), spec.name
        assert spec.scalars and spec.build.__module__ in catalogue.spec_modules(spec.name)


@pytest.mark.parametrize("path", ["harness/judge/compare.py", "harness/report/figures.py",
                                  "harness/study/catalogue.py", "harness/report/listings.py"])
def test_the_harness_names_no_scene(path: str) -> None:
    text = (REPO / path).read_text()
    assert not [name for name in NAMES if f'"{name}"' in text or f"'{name}'" in text or name in text.split()]


def _targets(study: str) -> dict[str, float]:
    """Each claim's target as the study resolves it (a computed one, "reference:NAME", at its group's first level)."""
    return {c.id: c.targets[0][2] if c.targets else c.target for c in load_study(study).claims}


def test_the_study_targets_that_are_properties_of_a_scene_are_its_reference_scalars() -> None:
    def expected(name: str, **params) -> dict[str, float]:
        return get_spec(name).reference.scalars(make_scene(name, **params), {})

    elastic, contact = _targets("elasticity"), _targets("contact-friction")
    assert expected("bar-compression") == {"E_eff": elastic["continuum-hooke-E"],
                                           "nu_eff": elastic["continuum-hooke-nu"]}
    assert expected("bar-tension-fracture") == {"failure_stress": elastic["mca-fracture-strength"]}
    assert expected("bar-tension-fracture", k=2.0)["failure_stress"] == 200e6  # sigma_c / k: k sigma in tension
    assert expected("block-contact-compression")["contact_pressure_mean"] == contact["contact-pressure"]
    share = expected("frictional-heating", speed=0.5, friction=0.6, duration=0.001, base_conductivity=60.5)
    assert share == {"heat_share_base": contact["heating-dissimilar-share"]}
    assert expected("frictional-heating")["heat_share_base"] == 0.5
    assert expected("bar-heat-paper") == {"bulk_median": _targets("heat-particles")["paper-bulk-one-third"]}
    assert expected("incline", angle=15.0) == {"slide_acceleration": _targets("stick-slip")["incline-stick-15"]}
    assert expected("stick-slip")["spring_peak_N"] == _targets("stick-slip")["stick-slip-breakaway"]


def test_the_history_figure_draws_a_cell_over_its_scene_reference_curve(tmp_path) -> None:
    t = np.linspace(0.0, 4e-3, 400)
    force = get_spec("stick-slip").reference.history(make_scene("stick-slip"), t)[0]
    cell = {"scene": "stick-slip", "scene_params": {}, "solver": "mca", "n": 4, "status": "ok",
            "diagnostics": {"history": {"columns": ["t", "spring_force", "velocity", "displacement"],
                                        "rows": np.stack([t, force, 0 * t, 0 * t], axis=1).tolist()}}}
    assert figures.history([cell], tmp_path / "h", "history")
    drawn = json.loads((tmp_path / "h.json").read_text())
    assert "rigid block (analytic)" in json.dumps(drawn)


@pytest.fixture
def plugin_scenes(monkeypatch):
    """The example plugin's scene module, importable and registered for this test only."""
    monkeypatch.syspath_prepend(str(PLUGIN))
    monkeypatch.setattr(catalogue.SCENES, "registered", dict(catalogue.SCENES.registered))
    from fd_heat import scenes  # the example plugin, importable only once its folder is on the path

    for spec in scenes.SPECS.values():
        register_scene(spec, "examples/fd-heat-plugin")
    return scenes


def test_a_plugin_scene_is_compared_with_the_plugin_reference(plugin_scenes) -> None:
    """long-bar-source's reference is the plugin's own series (it agrees with the heat family's slab to 1e-12);
    compare uses it with no harness edit and stores its kind."""
    scene = make_scene("long-bar-source")
    points = scene.sample_sets(3)["nodes"]
    exact = plugin_scenes.exact(scene, points)
    heat, mat = scene.conduction, scene.material
    slab = Slab(scene.box.length, mat.conductivity, mat.diffusivity, held=(0.0, 0.0), source=heat.source)
    assert np.allclose(exact, slab.transient(points[:, 2], heat.t_end) / heat.t_max, rtol=0, atol=1e-12)
    got = compare.errors(scene, {"nodes": {"points": points, "values": exact + 0.01}})
    assert got["nodes"]["l2"] == pytest.approx(0.01) and got["nodes"]["reference"] == "analytic"
    assert catalogue.spec_modules("long-bar-source") == ("fd_heat.scenes",)


def test_the_cell_key_covers_the_plugin_scene_module(tmp_path) -> None:
    """An edit of the plugin's scene module (a copy) changes the compare fingerprint of its scene's cells."""
    shutil.copytree(PLUGIN / "fd_heat", tmp_path / "fd_heat")
    probe = ("from fd_heat import scenes; from pcverify.harness.study.catalogue import register_scene, make_scene; "
             "from pcverify.harness.judge.compare import fingerprint; "
             "register_scene(scenes.LONG_BAR_SOURCE, 'test'); print(fingerprint(make_scene('long-bar-source')))")

    def fingerprint() -> str:
        return subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True,
                              env={**os.environ, "PYTHONPATH": str(tmp_path)}, cwd=tmp_path).stdout.strip()

    before = fingerprint()
    module = tmp_path / "fd_heat" / "scenes.py"
    module.write_text(module.read_text().replace("import math", "import math\nSHIFT = 1.0", 1))
    assert len(before) == 16 and fingerprint() != before
