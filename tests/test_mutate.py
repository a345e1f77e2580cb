"""`pcverify mutate`: a study's claims run on deliberate defects of the code.

A tiny study (the example plugin's finite differences at n = 2, 3, 4 and one scikit-fem cell) with two
mutants of the plugin's solver: a factor 2 in its update coefficient, as a unified diff in the study file (the
order claim catches it), and a factor 2 in a summary number no claim reads, as a find/replace in the mutants
file beside the study (it survives).  The kill matrix, mutants.json and the report
section say so; the real result cache is byte for byte what it was; `--strict` exits 1 for the survivor; a
rerun recomputes nothing.  A mutant whose edit is not Python, or whose module does not import, is invalid,
never killed; one that hangs is stopped at its time limit and is crashed.  The overlay is seen by Python and
by the code fingerprint: the edit changes the number `run --json` prints, the keys of the cells whose solver
reaches the file and only those; numba recompiles only the kernels whose closure holds the mutated module,
into the mutant's copy of the numba cache, never the real one.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from pcverify.fingerprint import module_fingerprint
from pcverify.harness.cli import main
from pcverify.harness.report.gates import mutant_gate
from pcverify.harness.run.mutation import caught_by, judge, kill_kind, overlaid, prune
from pcverify.harness.run.overlay import OverlayFinder

REPO = Path(__file__).resolve().parent.parent
EXAMPLE = REPO / "examples" / "fd-heat-plugin"
ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}

STUDY = '''
name = "tiny"
plugins = ["fd_heat.solver"]

[[group]]
id = "faces"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.2, dt = 0.005 }
solvers = ["fd-heat"]
n = [2, 3, 4]

[[group]]
id = "steady"
scene = "bar-heat-faces"
solvers = ["skfem"]
n = [2]

[[claim]]
id = "fd-order"
text = "fd-heat converges at second order"
table = "faces-fits"
select = { solver = "fd-heat", quantity = "nodes.l2" }
metric = "order"
reference = "analytic"
target = 2.0
tolerance = 0.3

[[claim]]
id = "skfem-exact"
text = "scikit-fem's Q1 nodes hold the linear steady profile exactly"
table = "steady-cells"
select = { solver = "skfem" }
metric = "err.nodes.linf"
reference = "analytic"
target = 0.0
tolerance = 1e-9
sense = "at-most"

[[mutant]]
name = "rate-doubled"
package = "fd_heat"
file = "solver.py"
diff = """
--- a/fd_heat/solver.py
+++ b/fd_heat/solver.py
@@ -68,3 +68,3 @@
             held[tuple(index)] = True
-        rate = alpha * dt / (h * h)
+        rate = 2.0 * alpha * dt / (h * h)
         rise = heat.source * dt / (scene.material.density * scene.material.heat_capacity)  # K per step
"""
breaks = "twice the diffusivity in the update"
expect = ["fd-order"]
'''

BESIDE = '''
[[mutant]]
name = "dt-reported-twice"
package = "fd_heat"
file = "solver.py"
find = '"dt": dt, "steps": steps'
replace = '"dt": 2 * dt, "steps": steps'
breaks = "twice the time step in the summary, which no claim reads"
'''


@pytest.fixture(scope="module")
def plugin_path(tmp_path_factory):
    """The example plugin's package importable (not installed): the study names its solver module as a plugin.
    A copy of the package alone: the example's folder may hold the egg-info of an in-tree pip build, whose
    entry point would register the solver a second time."""
    where = tmp_path_factory.mktemp("plugin")
    shutil.copytree(EXAMPLE / "fd_heat", where / "fd_heat", ignore=shutil.ignore_patterns("__pycache__"))
    sys.path.insert(0, str(where))
    yield where
    sys.path.remove(str(where))


def _files(folder: Path, skip: str = "") -> dict[str, str]:
    """sha256 of every file under `folder` (those under `skip` left out), by relative path."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*"))
            if p.is_file() and not (skip and p.relative_to(folder).parts[0] == skip)}


def _study(tmp_path: Path, extra: str = "", beside: str = BESIDE) -> Path:
    path = tmp_path / "tiny.toml"
    path.write_text(STUDY + extra)
    if beside:
        (tmp_path / "tiny.mutants.toml").write_text(beside)
    return path


def _mutate(*args: str, capsys) -> tuple[int, list[dict], str]:
    code = main(["mutate", *args, "--json"])
    out, err = capsys.readouterr()
    return code, json.loads(out) if out.strip() else [], err


def test_one_mutant_is_killed_one_survives_and_the_real_cache_is_untouched(plugin_path, tmp_path, capsys) -> None:
    study = _study(tmp_path)
    out, cache = tmp_path / "out", tmp_path / "out" / "cache"
    assert main(["study", str(study), "--out", str(out), "--json"]) == 0
    capsys.readouterr()
    before = _files(cache)
    assert len(before) == 4  # the baseline's four cells

    code, docs, err = _mutate(str(study), "--out", str(out), "--jobs", "2", "--strict", capsys=capsys)
    assert code == 1  # --strict: a survivor
    assert "pcverify: mutant survived: tiny/dt-reported-twice (fd_heat/solver.py: twice the time step" in err
    assert ("pcverify: 1 of 2 mutants are not killed by a claim that measures them (1 survived, 0 invalid, 0 crashed, "
            "0 killed incidentally) (--strict)") in err
    assert _files(cache, skip="mutants") == before  # the real result cache, byte for byte

    doc = json.loads((out / "tiny" / "mutants.json").read_text())
    assert doc == docs[0]
    killed, survived = doc["mutants"]
    assert (killed["name"], killed["status"], killed["caught_by"]) == ("rate-doubled", "killed", ["fd-order"])
    assert killed["claims"] == {"fd-order": {"baseline": "pass", "mutant": "fail", "passing": 1, "caught": [""],
                                             "incidental": []},
                                "skfem-exact": {"baseline": "pass", "mutant": "pass", "passing": 1, "caught": [],
                                                "incidental": []}}
    assert killed["kill"] == "expected"  # fd-order measured the order it declares
    assert (survived["name"], survived["status"], survived["caught_by"]) == ("dt-reported-twice", "survived", [])
    assert survived["origin"] == f"mutants file {tmp_path / 'tiny.mutants.toml'}"
    for m in (killed, survived):
        # the three fd-heat cells reach the mutated file: their keys change and they run again; the scikit-fem
        # cell's key does not (its solver does not reach fd_heat): copied from the baseline, not recomputed
        assert (m["cells_changed"], m["recomputed"], m["cells"]["cells"], m["seeded"]) == (3, 3, 4, 4)
    assert doc["claims"] == {"fd-order": {"baseline": "pass", "passing": 1, "kills": ["rate-doubled"],
                                          "descriptive": False},
                             "skfem-exact": {"baseline": "pass", "passing": 1, "kills": [], "descriptive": True}}
    matrix = pd.read_csv(out / "tiny" / "mutants-matrix.csv")
    assert matrix.to_dict("records") == [
        {"claim": "fd-order", "baseline": "pass", "kills": 1, "rate-doubled": "killed (fail)",
         "dt-reported-twice": "pass"},
        {"claim": "skfem-exact", "baseline": "pass", "kills": 0, "rate-doubled": "pass", "dt-reported-twice": "pass"}]
    page = (out / "index.html").read_text()
    assert "How strong are the claims? 2 mutants: 1 killed, 1 survived, 0 invalid, 0 crashed" in page
    assert "descriptive: kills no catalogued mutant" in page and "tiny/mutants-matrix.csv" in page

    # a rerun resumes from each mutant's own cache: nothing is computed again; only the killed one: exit 0
    code, docs, _ = _mutate(str(study), "--out", str(out), "--mutant", "rate-doubled", "--strict", capsys=capsys)
    assert code == 0
    (again,) = docs[0]["mutants"]
    assert (again["status"], again["recomputed"], again["cells"]["cached"]) == ("killed", 0, 4)
    assert _files(cache, skip="mutants") == before


def test_only_the_groups_a_claim_reads_run_and_group_narrows_them(plugin_path, tmp_path, capsys) -> None:
    """A group no claim reads cannot catch a mutant: neither the baseline nor a mutant runs its cells.  --group
    keeps that group's claims (and the groups they read) only."""
    extra = '''
[[group]]
id = "unclaimed"
scene = "bar-heat-faces"
solvers = ["fd-heat"]
n = [5]
'''
    study = _study(tmp_path, extra)
    code, docs, _ = _mutate(str(study), "--out", str(tmp_path / "out"), "--mutant", "rate-doubled", capsys=capsys)
    assert code == 0
    assert docs[0]["baseline"]["cells"] == 4  # not the unclaimed group's fifth cell
    (killed,) = docs[0]["mutants"]
    assert (killed["status"], killed["cells"]["cells"], killed["recomputed"]) == ("killed", 4, 3)

    code, docs, _ = _mutate(str(study), "--out", str(tmp_path / "out"), "--group", "steady", capsys=capsys)
    assert code == 0
    assert docs[0]["baseline"]["cells"] == 1
    assert set(docs[0]["claims"]) == {"skfem-exact"}
    assert [(m["name"], m["status"]) for m in docs[0]["mutants"]] == [("rate-doubled", "survived"),
                                                                      ("dt-reported-twice", "survived")]
    assert main(["mutate", "default", "--group", "steady"]) == 2
    assert "--group needs one study" in capsys.readouterr().err


def test_an_invalid_mutant_is_never_killed(plugin_path, tmp_path, capsys) -> None:
    """An edit that is not Python is invalid without running; a module that raises on import is invalid with
    its error; neither is counted as killed, and --strict fails on them."""
    extra = '''
[[mutant]]
name = "not-python"
package = "fd_heat"
file = "solver.py"
find = "rate = alpha * dt / (h * h)"
replace = "rate = alpha * dt / (h * h"
breaks = "a syntax error"

[[mutant]]
name = "no-import"
package = "fd_heat"
file = "solver.py"
find = 'AXIS = {"x": 0, "y": 1, "z": 2}'
replace = 'AXIS = UNDEFINED_NAME'
breaks = "a name that does not exist at import"
'''
    study = _study(tmp_path, extra, beside="")
    code, docs, err = _mutate(str(study), "--out", str(tmp_path / "out"), "--mutant", "not-python", "--mutant",
                              "no-import", "--strict", capsys=capsys)
    assert code == 1
    bad, broken = docs[0]["mutants"]
    assert bad["status"] == "invalid" and bad["reason"].startswith("the edited module is not valid Python (SyntaxError")
    assert bad["wall_s"] < 1.0  # refused before any process starts
    assert broken["status"] == "invalid"
    assert broken["reason"] == "fd_heat.solver does not import: NameError: name 'UNDEFINED_NAME' is not defined"
    assert docs[0]["counts"] == {"killed": 0, "survived": 0, "invalid": 2, "crashed": 0}
    assert ("pcverify: 2 of 2 mutants are not killed by a claim that measures them (0 survived, 2 invalid, 0 crashed, "
            "0 killed incidentally) (--strict)") in err


def test_a_mutant_that_hangs_is_stopped_at_its_time_limit_and_is_crashed(plugin_path, tmp_path, capsys) -> None:
    extra = '''
[[mutant]]
name = "hangs"
package = "fd_heat"
file = "solver.py"
find = 'AXIS = {"x"'
replace = 'AXIS = time.sleep(600) or {"x"'
breaks = "never finishes importing"
'''
    study = _study(tmp_path, extra, beside="")
    code, docs, _ = _mutate(str(study), "--out", str(tmp_path / "out"), "--mutant", "hangs",
                            "--mutant-time-limit", "3", capsys=capsys)
    assert code == 0  # not --strict
    (hung,) = docs[0]["mutants"]
    assert hung["status"] == "crashed" and hung["caught_by"] == []
    assert hung["reason"].startswith("exceeded the mutant time limit of 3 s")
    assert hung["wall_s"] < 20


def test_the_overlay_changes_the_number_and_the_keys_it_reaches(plugin_path, tmp_path) -> None:
    """In a mutant's process Python loads the edited module (`run --json` prints another error) and the code
    fingerprint reads it (the keys of fd-heat's cells change, scikit-fem's do not)."""
    study = _study(tmp_path, beside="")
    folder = tmp_path / "mutant"
    folder.mkdir()
    source = folder / "solver.py"
    original = plugin_path / "fd_heat" / "solver.py"
    source.write_text(original.read_text().replace("rate = alpha * dt / (h * h)", "rate = 2.0 * alpha * dt / (h * h)"))
    run = ["run", "bar-heat-faces", "--solver", "fd_heat.solver:FiniteDifferenceHeat", "--set", "mode=transient",
           "--set", "t_end=0.2", "--n", "3", "--json"]
    plan = ["study", str(study), "--dry-run", "--json", "--cache", str(tmp_path / "cache")]

    def outputs(module: str, path: Path) -> list:
        code, timed_out = overlaid(module, path, original, [run, plan], folder, 120.0)
        assert (code, timed_out) == (0, False), (folder / "run.log").read_text()[-2000:]
        return [r["json"] for r in json.loads((folder / "outcome.json").read_text())["results"]]

    (mutant_run, mutant_plan), (original_run, original_plan) = outputs("fd_heat.solver", source), \
        outputs("fd_heat.solver", original)
    assert mutant_run["errors"]["nodes"]["l2"] > 2 * original_run["errors"]["nodes"]["l2"]
    keys = {(r["solver"], r["cell"]): r["key"] for r in original_plan[0]["cells"]}
    changed = {(r["solver"], r["cell"]) for r in mutant_plan[0]["cells"] if keys[(r["solver"], r["cell"])] != r["key"]}
    assert {s for s, _ in changed} == {"fd-heat"} and len(changed) == 3 and len(keys) == 4


def test_numba_recompiles_only_what_the_mutant_reaches_and_never_in_the_real_cache(tmp_path) -> None:
    """A mutant of the MCA heat kernel (heat.py) on a study with an MCA heat cell and an MCA compression cell (each
    read by a claim, so both run):
    numba compiles heat.py's kernels in the mutant's copy of the numba cache and loads those of kernel.py,
    which does not import heat.py; the real numba cache and the real result cache are byte for byte unchanged.
    A mutant whose kernel numba cannot type is invalid, not killed.
    (Both studies run as the command line: NUMBA_CACHE_DIR is read when numba is imported.)"""
    real = tmp_path / "numba"
    if os.environ.get("NUMBA_CACHE_DIR") and Path(os.environ["NUMBA_CACHE_DIR"]).is_dir():
        shutil.copytree(os.environ["NUMBA_CACHE_DIR"], real, ignore=shutil.ignore_patterns("*.tmp.*"))
    env = {**ENV, "NUMBA_CACHE_DIR": str(real), "NUMBA_DEBUG_CACHE": "1"}
    study = tmp_path / "mca.toml"
    study.write_text('''
name = "mca-small"

[[group]]
id = "heat"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.2 }
solvers = ["mca"]
n = [2]

[[group]]
id = "compression"
scene = "bar-compression"
solvers = ["mca"]
n = [2]

[[claim]]
id = "heat-mean"
text = "the mean temperature at t = 0.2 s"
table = "heat-cells"
select = { solver = "mca" }
metric = "volume_mean"
reference = "theory"
target = 0.2287
tolerance = 0.001

[[claim]]
id = "compression-modulus"
text = "the effective Young's modulus of the compressed bar"
table = "compression-cells"
select = { solver = "mca" }
metric = "E_eff"
reference = "theory"
target = 70e9
tolerance_rel = 1e-6

[[mutant]]
name = "heat-flow-half"
file = "solvers/particles/mca/heat.py"
find = "temp[i] += dt * flow[i] / cap[i]"
replace = "temp[i] += 0.5 * dt * flow[i] / cap[i]"
breaks = "half the heat flow reaches each automaton's temperature"

[[mutant]]
name = "heat-untyped"
file = "solvers/particles/mca/heat.py"
find = "temp[i] += dt * flow[i] / cap[i]"
replace = "temp[i] += dt * flow[i] / cap"
breaks = "an array where a number belongs: numba cannot type the kernel"
''')

    def pcverify(*args: str) -> subprocess.CompletedProcess:
        done = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", *args, "--out", str(tmp_path / "out")],
                              capture_output=True, text=True, cwd=tmp_path, env=env, check=False, timeout=600)
        assert done.returncode == 0, done.stderr[-3000:]
        return done

    pcverify("study", str(study), "--json")
    numba_before, cache_before = _files(real), _files(tmp_path / "out" / "cache")
    doc = json.loads(pcverify("mutate", str(study), "--jobs", "2", "--json").stdout)[0]
    m, untyped = doc["mutants"]
    # a kernel that does not compile: the heat cell failed with numba's TypingError (the compression cell, whose
    # key changed too, does not call the heat kernel)
    assert untyped["status"] == "invalid" and untyped["caught_by"] == []
    assert untyped["reason"].startswith("its code does not compile or import: 1 of the 2 cells whose key it changed "
                                        "failed so, e.g. TypingError: Failed in nopython mode pipeline")
    assert (m["status"], m["caught_by"], m["recomputed"]) == ("killed", ["heat-mean"], 2)
    assert _files(real) == numba_before
    assert _files(tmp_path / "out" / "cache", skip="mutants") == cache_before
    saved = {Path(line.split("saved to ")[1].strip("'")).name.split("-")[0]
             for line in (Path(m["folder"]) / "run.log").read_text().splitlines() if "data saved to" in line}
    assert saved == {"heat._explicit", "heat.explicit_run"}  # kernel.py's kernels were loaded, not compiled
    assert not (Path(m["folder"]) / "numba").exists()  # the copy goes once the mutant is judged


def test_a_mutant_of_the_run_code_starts_from_an_empty_result_cache(plugin_path, tmp_path, capsys) -> None:
    """How cells run is not in their keys: a mutant of harness/run gets no copy of the baseline's entries and
    computes every cell, although no key changes."""
    extra = '''
[[mutant]]
name = "run-code"
file = "harness/run/execution.py"
find = 'res.setdefault("h", resolution.spacing(scene.box.width))'
replace = 'res.setdefault("h", float(resolution.spacing(scene.box.width)))'
breaks = "nothing: the spacing converted to the float it already is"
'''
    study = _study(tmp_path, extra, beside="")
    code, docs, _ = _mutate(str(study), "--out", str(tmp_path / "out"), "--mutant", "run-code", capsys=capsys)
    assert code == 0
    (m,) = docs[0]["mutants"]
    assert (m["status"], m["seeded"], m["cells_changed"], m["recomputed"]) == ("survived", 0, 0, 4)


def test_an_edited_mutant_replaces_its_own_folder_and_no_other(tmp_path) -> None:
    """A mutant's folder is named by its name and the hash of its definition and edited source: a new hash
    removes the mutant's older folders, never those of a mutant whose name extends its own."""
    root = tmp_path / "mutants" / "s"
    for name in ("a-0123456789ab", "a-b-0123456789ab", "ab-0123456789ab", "a-notahash"):
        (root / name).mkdir(parents=True)
    prune(root / "a-fedcba987654")
    assert sorted(p.name for p in root.iterdir()) == ["a-b-0123456789ab", "a-notahash", "ab-0123456789ab"]


def test_the_code_fingerprint_reads_the_overlay(tmp_path, monkeypatch) -> None:
    """The overlay's finder is one of sys.meta_path's, which the fingerprint resolves names through (without
    importing): a module whose closure holds the overlaid one gets another fingerprint, a module that does not
    reach it keeps its own."""
    package = tmp_path / "ovl_pkg"
    package.mkdir()
    (package / "__init__.py").write_text("")
    (package / "a.py").write_text("from ovl_pkg import b\n")
    (package / "b.py").write_text("X = 1\n")
    (package / "c.py").write_text("Y = 1\n")
    (tmp_path / "b_edited.py").write_text("X = 2\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    before = {m: module_fingerprint(f"ovl_pkg.{m}") for m in "abc"}
    finder = OverlayFinder("ovl_pkg.b", str(tmp_path / "b_edited.py"), str(package / "b.py"))
    monkeypatch.setattr(sys, "meta_path", [finder, *sys.meta_path])
    after = {m: module_fingerprint(f"ovl_pkg.{m}") for m in "abc"}
    assert after["a"] != before["a"] and after["b"] != before["b"] and after["c"] == before["c"]
    assert "ovl_pkg" not in sys.modules  # resolved, never imported


def test_a_claim_judged_per_case_catches_a_mutant_with_any_case_that_passed() -> None:
    """A claim with one failing case (n=3) and one passing case (n=8): on a mutant that breaks n=8 it has caught
    the defect, though its worst state was fail on the original too; a case failing on both catches nothing."""
    def rows(n3: str, n8: str) -> list[dict[str, str]]:
        return [{"claim": "c", "case": "n=3", "verdict": n3}, {"claim": "c", "case": "n=8", "verdict": n8}]

    claims = judge(rows("fail", "pass"), rows("fail", "inconclusive"))
    assert claims == {"c": {"baseline": "fail", "mutant": "fail", "passing": 1, "caught": ["n=8"],
                            "incidental": ["n=8"]}}  # these records carry no value: nothing was measured
    assert caught_by(claims) == ["c"]
    assert caught_by(judge(rows("fail", "pass"), rows("pass", "pass"))) == []


def test_a_kill_is_expected_measuring_or_incidental() -> None:
    """A claim whose number moved beyond its bound measured the defect (expected where the mutant names it); a
    claim that failed only because its cells did not run to a value (out of steps, stopped) caught it
    incidentally, and --strict does not count such a kill."""
    base = [{"claim": "a", "case": "", "verdict": "pass", "value": 1.0},
            {"claim": "b", "case": "", "verdict": "pass", "value": 2.0}]
    moved = [{"claim": "a", "case": "", "verdict": "fail", "value": 1.5}, base[1]]
    unjudged = [{"claim": "a", "case": "", "verdict": "fail", "value": None,
                 "note": "not judged on all its cells: n=4 non-stationary"}, base[1]]
    assert kill_kind(judge(base, moved), expect=["a"]) == "expected"
    assert kill_kind(judge(base, moved), expect=["b"]) == "measuring"
    assert kill_kind(judge(base, unjudged), expect=["a"]) == "incidental"
    assert kill_kind(judge(base, base), expect=[]) == ""
    doc = {"study": "s", "mutants": [{"name": "m", "status": "killed", "kill": "incidental", "package": "p",
                                      "file": "f.py", "breaks": "b", "reason": "caught only where no claim "
                                      "measured it: a ()"}]}
    assert mutant_gate([doc], strict=True) == 1 and mutant_gate([doc], strict=False) == 0


MAIN_MODULES = '''
name = "main-modules"

[[group]]
id = "steady"
scene = "bar-heat-faces"
solvers = ["fipy", "skfem", "mca", "macromolecule"]
n = [2]
solver_params = { macromolecule = { t_end = 0.5, stop_tol = 0.0 } }

[[claim]]
id = "steady-mean"
text = "the continuum solvers and the MCA hold the steady linear profile's mean, 1/2"
table = "steady-cells"
select = { solver = ["fipy", "skfem", "mca"] }
per = "solver"
metric = "volume_mean"
reference = "analytic"
target = 0.5
tolerance = 1e-9
'''
# each shipped solver package's main module, edited where no cell of the study above reads it (the mutant
# survives): what is checked is that the mutant's study runs to its verdicts
MAIN_EDITS = (("solvers/particles/mca/solver.py", "MIN_PEAK_STEPS = 50", "MIN_PEAK_STEPS = 51"),
              ("solvers/particles/macromolecule/solver.py", "BYTES_PER_PARTICLE = 3_000", "BYTES_PER_PARTICLE = 3_001"),
              ("solvers/continuum/fipy_heat.py", "SUBSAMPLES = 8", "SUBSAMPLES = 9"),
              ("solvers/continuum/skfem_heat.py", '"heat-source-field", "interface-flux"})',
               '"heat-source-field"})'),
              ("solvers/particles/lammps_bpm/solver.py", "HISTORY_ROWS = 2000", "HISTORY_ROWS = 2001"),
              ("solvers/continuum/skfem_elastic.py", '"q2": ("ElementHex2", 4, 2)', '"q2": ("ElementHex2", 5, 2)'))


def test_a_mutant_of_each_solver_package_main_module_reaches_its_verdicts(tmp_path, capsys) -> None:
    """The mutant's edited copy stands in a folder of its own: a module that reads a data file beside it (the
    MCA solver its model notes) finds it there too, so a mutant of any shipped solver module is judged, never
    crashed on a missing file."""
    mutants = "".join(f'\n[[mutant]]\nname = "main-{i}"\nfile = "{file}"\nfind = \'{find}\'\nreplace = \'{new}\'\n'
                      f'breaks = "a change no claim of this study reads"\n'
                      for i, (file, find, new) in enumerate(MAIN_EDITS))
    study = tmp_path / "main-modules.toml"
    study.write_text(MAIN_MODULES + mutants)
    assert main(["study", str(study), "--out", str(tmp_path / "out"), "--json"]) == 0
    capsys.readouterr()
    code, docs, err = _mutate(str(study), "--out", str(tmp_path / "out"), "--jobs", "2", capsys=capsys)
    outcomes = {m["file"]: (m["status"], m.get("reason")) for m in docs[0]["mutants"]}
    assert set(outcomes) == {file for file, _, _ in MAIN_EDITS}, outcomes
    assert all(status == "survived" for status, _ in outcomes.values()), (outcomes, err[-2000:])
    assert code == 0 and docs[0]["mutants"][0]["claims"]["steady-mean"]["mutant"] == "pass"
