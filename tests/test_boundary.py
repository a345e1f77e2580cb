"""The trust boundary: whatever a solver returns is checked before it is stored.

Hostile plugin solvers (values at one point, points a quarter bar away, no `nodes` set, a short value array,
a set without points, complex or text numbers in the summary and the parameters, NaN values called ok, a
dict or None instead of a Solution, an exception) each give a failed cell whose reason names the solver and
the field: through `pcverify run --solver module:Class --json` (exit 1) and in a study with `plugins = [...]`
(the stored result is failed; its claim on err.nodes.l2 is not passed).  A correct plugin is unaffected.
"""

from __future__ import annotations

import dataclasses
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.judge.metrics import field_errors
from pcverify.harness.study.boundary import Inadmissible, admitted
from pcverify.harness.study.catalogue import get_spec, make_scene
from pcverify.references.heat import analytic
from pcverify.scene import Resolution
from pcverify.solvers.continuum.skfem_elastic import SkfemElastic
from pcverify.solvers.protocol import Solution

REPO = Path(__file__).resolve().parent.parent
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}

HOSTILE = '''
"""Plugin solvers of the steady face-heated bar: one correct, the others each break one field of the output."""
import numpy as np
from pcverify import FaceTemperature, Param, Solution, effective_params


class Exact:
    """The exact linear profile between the held z faces, at the scene's points."""

    name = "exact"
    kind = "continuum"
    parameters = (Param("scale", 1.0, "", "factor on the result", low=0.0, high=10.0),)

    def supports(self, scene):
        faces = {c.face for c in scene.constraints if isinstance(c, FaceTemperature)}
        ok = scene.physics == frozenset({"conduction"}) and faces == {"z0", "zL"} and scene.conduction.mode == "steady"
        return ok, "" if ok else "the steady face-heated bar only"

    def solve(self, scene, resolution, samples=None, **params):
        p = effective_params(self, params)
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {k: {"points": np.asarray(v, float), "values": p["scale"] * (1.0 - v[:, 2] / scene.box.length)}
               for k, v in sets.items()}
        sol = Solution(scene=scene.name, solver=self.name, params=p,
                       resolution={"n": resolution.n, "refine": resolution.refine}, samples=out,
                       unknowns=len(out["nodes"]["values"]), wall_s=0.0,
                       summary={"bulk_median": 0.5, "volume_mean": 0.5})
        return self.mangle(sol, scene)

    def mangle(self, sol, scene):
        return sol


class OnePoint(Exact):
    name = "one-point"

    def mangle(self, sol, scene):
        nodes = sol.samples["nodes"]
        sol.samples["nodes"] = {"points": nodes["points"][:1], "values": nodes["values"][:1]}
        return sol


class Shifted(Exact):
    """Points a quarter bar along z, with the exact profile at those points (zero error where it stands)."""
    name = "shifted"

    def mangle(self, sol, scene):
        pts = sol.samples["nodes"]["points"] + np.array([0.0, 0.0, scene.box.length / 4])
        sol.samples["nodes"] = {"points": pts, "values": 1.0 - pts[:, 2] / scene.box.length}
        return sol


class NoNodes(Exact):
    name = "no-nodes"

    def mangle(self, sol, scene):
        del sol.samples["nodes"]
        return sol


class ShortValues(Exact):
    name = "short-values"

    def mangle(self, sol, scene):
        sol.samples["nodes"]["values"] = sol.samples["nodes"]["values"][:-1]
        return sol


class NoPoints(Exact):
    name = "no-points"

    def mangle(self, sol, scene):
        del sol.samples["nodes"]["points"]
        return sol


class ComplexSummary(Exact):
    name = "complex-summary"

    def mangle(self, sol, scene):
        sol.summary["bulk_median"] = complex(0.5, 0.0)
        return sol


class TextSummary(Exact):
    name = "text-summary"

    def mangle(self, sol, scene):
        sol.summary["bulk_median"] = "0.5"
        return sol


class ComplexParams(Exact):
    name = "complex-params"

    def mangle(self, sol, scene):
        sol.params["scale"] = complex(1.0, 0.0)
        return sol


class TextParams(Exact):
    name = "text-params"

    def mangle(self, sol, scene):
        sol.params["scale"] = "1.0"
        return sol


class NanOk(Exact):
    name = "nan-ok"

    def mangle(self, sol, scene):
        sol.samples["nodes"]["values"][3] = np.nan
        return sol


class ReturnsDict(Exact):
    name = "returns-dict"

    def mangle(self, sol, scene):
        return sol.to_dict()


class ReturnsNone(Exact):
    name = "returns-none"

    def mangle(self, sol, scene):
        return None


class Raises(Exact):
    name = "raises"

    def mangle(self, sol, scene):
        raise RuntimeError("boom")
'''

# class -> (solver name, words the failed cell's reason holds; bar-heat-faces at n = 3 asks for 63 nodes)
CASES = {
    "OnePoint": ("one-point", "solver 'one-point' returned samples['nodes'] with 1 point; the scene asks for 63"),
    "Shifted": ("shifted", "solver 'shifted' returned samples['nodes'] at points other than the scene's: 63 points "
                "off, the first (point 0) by 0.0075 m from (0, 0, 0)"),
    "NoNodes": ("no-nodes", "solver 'no-nodes' returned no samples['nodes']; the scene asks for nodes, "
                "front_top_edge, bottom_back_edge"),
    "ShortValues": ("short-values", "solver 'short-values' returned samples['nodes']['values'] of shape (62,) for "
                    "63 points"),
    "NoPoints": ("no-points", "solver 'no-points' returned samples['nodes'] without 'points'"),
    "ComplexSummary": ("complex-summary", "solver 'complex-summary' returned summary['bulk_median'] = (0.5+0j), a "
                       "complex number"),
    "TextSummary": ("text-summary", "solver 'text-summary' returned summary['bulk_median'] = '0.5', a number as "
                    "text"),
    "ComplexParams": ("complex-params", "solver 'complex-params' returned params['scale'] = (1+0j), a complex "
                      "number; allowed: number in [0, 10]"),
    "TextParams": ("text-params", "solver 'text-params' returned params['scale'] = '1.0', a number as text; "
                   "allowed: number in [0, 10]"),
    "NanOk": ("nan-ok", "solver 'nan-ok' returned samples['nodes'] with 1 non-finite value (nan at point 3) and "
              "status ok"),
    "ReturnsDict": ("returns-dict", "solver 'returns-dict' returned a dict ("),
    "ReturnsNone": ("returns-none", "solver 'returns-none' returned a NoneType (None), not a Solution"),
    "Raises": ("raises", "RuntimeError: boom"),
}


@pytest.fixture(scope="module")
def plugin_dir(tmp_path_factory) -> Path:
    """The hostile plugin module in a folder of its own (on sys.path for the in-process runs)."""
    where = tmp_path_factory.mktemp("hostile")
    (where / "hostile_plugin.py").write_text(HOSTILE)
    sys.path.insert(0, str(where))
    yield where
    sys.path.remove(str(where))
    sys.modules.pop("hostile_plugin", None)


def _run(argv: list[str], capsys) -> tuple[int, dict]:
    code = main(argv)
    out, err = capsys.readouterr()
    assert "Traceback" not in err, err
    return code, json.loads(out)


@pytest.mark.parametrize("cls", sorted(CASES))
def test_run_refuses_a_hostile_output_as_a_failed_cell(cls, plugin_dir, capsys) -> None:
    """`pcverify run --solver hostile_plugin:Class --json`: exit 1, status failed, the reason names the solver
    and the field; every key of the JSON interface is there, and nothing of the refused output is."""
    name, words = CASES[cls]
    code, out = _run(["run", "bar-heat-faces", "--solver", f"hostile_plugin:{cls}", "--n", "3", "--json"], capsys)
    assert code == 1 and out["status"] == "failed", out
    assert words in out["reason"], out["reason"]
    if cls == "Raises":
        assert out["reason"] == "RuntimeError: boom"
    assert out["samples"] == {} and out["summary"] == {} and out["errors"] == {}
    for key in ("scene", "scene_params", "scene_hash", "solver", "params", "resolution", "unknowns", "wall_s",
                "status", "reason", "quantity", "samples", "summary", "work", "diagnostics", "errors"):
        assert key in out, key


def test_the_command_line_refuses_it_in_a_subprocess_too(plugin_dir) -> None:
    """The installed entry point, in a process of its own: one JSON object, exit 1, no traceback."""
    done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "run", "bar-heat-faces", "--solver",
                           "hostile_plugin:Shifted", "--n", "3", "--json"], capture_output=True, text=True,
                          env={**ENV, "PYTHONPATH": str(plugin_dir)}, cwd=plugin_dir, check=False)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr[-2000:]
    out = json.loads(done.stdout)
    assert out["status"] == "failed" and CASES["Shifted"][1] in out["reason"]


STUDY = """
name = "hostile"
title = "plugin outputs at the trust boundary"
plugins = ["hostile_plugin"]

[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = [SOLVERS]
n = [3]

[[group]]
id = "fd"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 1.0, dt = 0.01 }
solvers = ["fd_heat.solver:FiniteDifferenceHeat"]
n = [2, 3]

[[claim]]
id = "exact"
text = "Each solver reproduces the steady line at the scene's nodes"
table = "faces-cells"
per = "solver"
metric = "err.nodes.l2"
reference = "analytic"
tolerance = 1e-9
"""


@pytest.fixture(scope="module")
def study(plugin_dir) -> Path:
    """The hostile solvers and the correct one in a study (a process of its own: the plugin module registers
    its solvers there, not in the test process); returns the report folder."""
    names = ", ".join(f'"{n}"' for n, _ in CASES.values())
    (plugin_dir / "hostile.toml").write_text(STUDY.replace("SOLVERS", f'"exact", {names}'))
    env = {**ENV, "PYTHONPATH": os.pathsep.join([str(plugin_dir), str(REPO / "examples" / "fd-heat-plugin")])}
    done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "study", "hostile.toml", "--out", "out",
                           "--json", "--strict"], capture_output=True, text=True, env=env, cwd=plugin_dir,
                          check=False)
    assert "Traceback" not in done.stderr, done.stderr[-3000:]
    assert done.returncode in (0, 1), done.stderr[-3000:]
    return plugin_dir / "out"


def _stored(out: Path) -> dict[str, dict]:
    """The cache's stored results by solver."""
    entries = [json.loads(p.read_text())["result"] for p in (out / "cache").glob("*.json")]
    return {r["solver"]: r for r in entries}


def test_a_study_stores_each_hostile_output_as_failed(study) -> None:
    """In a study (plugins = [...]), each stored result of a hostile solver is failed with the same reason as
    `run` gives, nothing of its output is kept, and the correct solver's cell is ok with errors ~1e-16."""
    stored = _stored(study)
    for name, words in CASES.values():
        r = stored[name]
        assert r["status"] == "failed" and words in r["reason"], (name, r.get("reason"))
        assert "samples" not in r and "errors" not in r
    exact = stored["exact"]
    assert exact["status"] == "ok" and exact["errors"]["nodes"]["reference"] == "analytic"
    assert exact["errors"]["nodes"]["l2"] < 1e-15 and exact["errors"]["nodes"]["linf"] < 1e-15
    cells = pd.read_csv(study / "hostile" / "faces-cells.csv").set_index("solver")
    assert cells.loc["exact", "status"] == "ok"
    assert set(cells.drop(index="exact")["status"]) == {"failed"}
    assert cells.drop(index="exact")["err.nodes.l2"].isna().all()


def test_no_claim_passes_on_a_hostile_output(study) -> None:
    """The claim on err.nodes.l2 (tolerance 1e-9) passes for the correct solver only: the points of a
    solver's own choosing no longer give it a zero error."""
    verdicts = pd.read_csv(study / "hostile" / "verdicts.csv")
    passed = set(verdicts[verdicts["verdict"] == "pass"]["case"])
    assert passed == {"solver=exact"}, verdicts[["case", "verdict"]]


def test_a_correct_plugin_is_unaffected(study) -> None:
    """The fd-heat example (module:Class in the study, no install) is ok; its stored samples and summary are
    those of a direct solve, and its stored errors are field_errors of them against the analytic reference."""
    sys.path.insert(0, str(REPO / "examples" / "fd-heat-plugin"))
    try:
        from fd_heat.solver import FiniteDifferenceHeat  # the example plugin, not installed here
    finally:
        sys.path.remove(str(REPO / "examples" / "fd-heat-plugin"))
    entries = [json.loads(p.read_text())["result"] for p in (study / "cache").glob("*.json")]
    # a stored result carries the solver as its cell named it, not the name the class gives itself
    fd = {r["n"]: r for r in entries if r["solver"] == "fd_heat.solver:FiniteDifferenceHeat"}
    assert sorted(fd) == [2, 3]
    scene = make_scene("bar-heat-faces", mode="transient", t_end=1.0, dt=0.01)
    for n, r in fd.items():
        direct = FiniteDifferenceHeat().solve(scene, Resolution(n)).to_dict()
        assert r["status"] == "ok" and r["samples"] == direct["samples"] and r["summary"] == direct["summary"]
        for name, s in r["samples"].items():
            pts = np.asarray(s["points"], dtype=float)
            expected = field_errors(np.asarray(s["values"], dtype=float), analytic(scene, pts))
            assert r["errors"][name] == expected | {"reference": "analytic"}
    assert 1e-4 < fd[3]["errors"]["nodes"]["linf"] < fd[2]["errors"]["nodes"]["linf"] < 0.1


def test_a_summary_scalar_against_its_familys_sign_convention_is_named():
    """The elastic family says reaction_force has the sign of the imposed strain: scikit-fem's compression gives
    a negative reaction and passes; the same solution with the reaction reported positive (as a plugin once did)
    fails, naming the scalar and the convention (the fracture scene, pulled, expects it positive)."""
    solver = SkfemElastic()
    for strain in (-1e-3, -5e-3):
        scene = make_scene("bar-compression", strain=strain)
        sol = solver.solve(scene, Resolution(2))
        assert np.sign(sol.summary["reaction_force"]) == np.sign(strain) and sol.summary["E_eff"] > 0
        assert admitted(sol, solver, scene, Resolution(2))["summary"]["reaction_force"] == sol.summary["reaction_force"]
        flipped = dataclasses.replace(sol, summary=sol.summary | {"reaction_force": -sol.summary["reaction_force"]})
        with pytest.raises(Inadmissible, match=r"summary\['reaction_force'\] = .*, positive; allowed: negative on "
                           r"this scene \(axial force the support on face zL applies"):
            admitted(flipped, solver, scene, Resolution(2))
    pulled = make_scene("bar-tension-fracture")
    assert [s.sign(pulled) for s in get_spec(pulled.name).scalars if s.name == "reaction_force"] == [1]


def test_a_record_without_a_field_names_the_scenes_quantity():
    """A failed solution on an elastic scene says its quantity is the displacement, not the default T/t_max."""
    solver = SkfemElastic()
    scene = make_scene("bar-compression")
    failed = Solution(scene=scene.name, solver=solver.name, params={}, resolution={}, samples={}, unknowns=0,
                      wall_s=0.0, status="failed", reason="stopped")
    assert failed.quantity == "T/t_max"  # the protocol's default, for heat
    assert admitted(failed, solver, scene, Resolution(2))["quantity"] == "u (m)" == scene.quantity
    assert make_scene("bar-modes").quantity == "mode-1 shape (max |u| = 1)"
    assert make_scene("bar-heat-faces").quantity == "T/t_max"
