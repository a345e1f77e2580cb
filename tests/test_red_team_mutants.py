"""Red team, mutants: a `[[mutant]]` table, a mutants file beside a study, a plugin's entry point and the
`--mutant` selection are user input.  A misspelt key, a missing sentence, both or neither of find and diff, a
name declared twice, a path that leaves its package (`..`, absolute), a module that is not there, a find text
that does not occur as often as declared, a diff that does not match, an unknown mutant name or a plugin's
entry point that raises: each is one error line naming the mutant, its source and what is allowed (exit 2),
before the baseline or any mutant runs.  A study with a stale mutant still runs as a study.  The command runs
in this process: a refusal needs no process of its own."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from red_team import check_tally, one_line_error, run, tally

from pcverify.harness.study.mutants import Mutant, MutantError, apply_diff

TABLES = "mutant tables"
EDITS = "mutant edits"
EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "fd-heat-plugin"

STUDY = '''name = "s"
plugins = ["fd_heat.solver"]
[[group]]
id = "g"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.1 }
solvers = ["fd-heat"]
n = [2]
'''
GOOD = '''
[[mutant]]
name = "good"
package = "fd_heat"
file = "solver.py"
find = "rate = alpha * dt / (h * h)"
replace = "rate = 2.0 * alpha * dt / (h * h)"
breaks = "twice the diffusivity"
'''


def _mutant(**fields: object) -> str:
    """One [[mutant]] table: GOOD's fields with `fields` replacing them (None: left out)."""
    table = {"name": '"m"', "package": '"fd_heat"', "file": '"solver.py"', "find": "'rate = alpha * dt / (h * h)'",
             "replace": "'rate = 2.0 * alpha * dt / (h * h)'", "breaks": '"twice the diffusivity"'}
    table |= {k: v for k, v in fields.items()}
    return "\n[[mutant]]\n" + "".join(f"{k} = {v}\n" for k, v in table.items() if v is not None)


@pytest.fixture(scope="module")
def plugin_copy(tmp_path_factory):
    """The example plugin's package alone (the example's folder may hold the egg-info of an in-tree pip build,
    whose entry point would register its solver a second time)."""
    where = tmp_path_factory.mktemp("plugin")
    shutil.copytree(EXAMPLE / "fd_heat", where / "fd_heat", ignore=shutil.ignore_patterns("__pycache__"))
    return where


@pytest.fixture(autouse=True)
def plugin_path(monkeypatch, plugin_copy):
    monkeypatch.syspath_prepend(str(plugin_copy))


REFUSED_TABLES = [
    ("unknown key", _mutant(colour='"red"'), "s.toml: mutant[1] (m): colour is not a field of [[mutant]]; allowed: "
     "name, package, file, find, replace, count, diff, breaks, expect"),
    ("no sentence", _mutant(breaks=None), "mutant[1] (m): breaks is missing; allowed: a sentence"),
    ("an empty sentence", _mutant(breaks='"   "'), "mutant[1] (m): breaks=' ' is not valid; allowed: a sentence"),
    ("find and diff", _mutant(diff='"@@ -1 +1 @@"'), "mutant[1] (m): find and diff are given; allowed: exactly one "
     "of find, diff"),
    ("neither find nor diff", _mutant(find=None, replace=None), "none of find, diff is given; allowed: exactly one"),
    ("find without replace", _mutant(replace=None), "mutant[1] (m): replace is missing; allowed: the text that "
     "replaces find"),
    ("replace with diff", _mutant(find=None, diff='"@@ -1 +1 @@"'), "mutant[1] (m): replace is given with diff; "
     "allowed: find, replace and count, or diff alone"),
    ("count 0", _mutant(count=0), "mutant[1] (m): count=0 is not valid; allowed: integer in [1, 1000]"),
    ("a name with a slash", _mutant(name='"a/b"'), "mutant[1] (a/b): name='a/b' is not valid; allowed: 1 to 80 "
     "letters"),
    ("expect not a claim id", _mutant(expect=3), "mutant[1] (m): expect=3 is not valid; allowed: a claim id, or a "
     "list of them"),
    ("a name twice", _mutant() + _mutant(), "mutant[2] (m): name='m' is not valid; allowed: a name no other mutant "
     "has (mutant[1] has it)"),
]


@pytest.mark.parametrize(("what", "table", "message"), REFUSED_TABLES, ids=[c[0] for c in REFUSED_TABLES])
def test_a_bad_mutant_table_is_one_line_naming_it(what, table, message, tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text(STUDY + table)
    line = one_line_error(run("mutate", "s.toml", cwd=tmp_path, capfd=capfd))
    assert message in line, line
    assert not (tmp_path / "reports").exists()  # refused before the baseline ran
    tally(TABLES, "rejected")


def test_a_mutants_file_beside_the_study_holds_mutants_only_and_no_name_twice(tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text(STUDY + _mutant())
    (tmp_path / "s.mutants.toml").write_text('[[group]]\nid = "x"\n')
    line = one_line_error(run("mutate", "s.toml", cwd=tmp_path, capfd=capfd))
    assert f"mutants file {tmp_path / 's.mutants.toml'}: group is not a field of a mutants file; allowed: mutant" \
        in line
    tally(TABLES, "rejected")
    (tmp_path / "s.mutants.toml").write_text(_mutant())
    line = one_line_error(run("mutate", "s.toml", cwd=tmp_path, capfd=capfd))
    assert line == (f"pcverify: error: mutant name 'm' is declared twice: in study file s.toml and in mutants file "
                    f"{tmp_path / 's.mutants.toml'}; allowed: one mutant per name")
    tally(TABLES, "rejected")


def test_a_study_with_a_stale_mutant_still_runs_as_a_study(tmp_path, capfd) -> None:
    """The edits are checked by `mutate` only: `study` runs a study whose mutant no longer applies."""
    (tmp_path / "s.toml").write_text(STUDY + _mutant(find="'text that is not there'"))
    assert run("study", "s.toml", "--json", cwd=tmp_path, capfd=capfd).returncode == 0
    tally(TABLES, "accepted")


REFUSED_EDITS = [
    ("find not there", _mutant(find="'rate = 3 * alpha'"), "pcverify: error: mutant 'm' (study file s.toml): "
     "find='rate = 3 * alpha' occurs 0 times in fd_heat/solver.py; allowed: exactly count=1"),
    ("find twice, count 1", _mutant(find="'temp'"), "find='temp' occurs 12 times in fd_heat/solver.py; allowed: "
     "exactly count=1"),
    ("a path up and out", _mutant(file='"../fd_heat/solver.py"'), "mutant 'm' (study file s.toml): "
     "file='../fd_heat/solver.py' is not valid; allowed: a relative path of a .py module inside package 'fd_heat'"),
    ("an absolute path", _mutant(file=f'"{EXAMPLE}/fd_heat/solver.py"'), "is not valid; allowed: a relative path of "
     "a .py module inside package 'fd_heat' (folders and module names are Python names: no '..', no absolute path)"),
    ("a module that is not there", _mutant(file='"solvers.py"'), "mutant 'm' (study file s.toml): "
     "file='solvers.py' is not a module of package 'fd_heat'; allowed: a relative path of a .py file inside"),
    ("not a module", _mutant(file='"pyproject.toml"'), "file='pyproject.toml' is not valid; allowed: a relative path "
     "of a .py module"),
    ("a package that is not there", _mutant(package='"no_such_package"'), "package='no_such_package' is not an "
     "importable package; allowed: the top-level package of a solver"),
    ("a module, not a package", _mutant(package='"csv"', file='"solver.py"'), "package='csv' is not an "
     "importable package"),
    ("a diff that does not match", _mutant(find=None, replace=None, diff='"@@ -3,1 +3,1 @@\\n-nothing\\n+else\\n"'),
     "mutant 'm' (study file s.toml): diff: hunk 1 (@@ -3) does not match the file; allowed: a diff against the file"),
    ("a diff without hunks", _mutant(find=None, replace=None, diff='"just text"'),
     "diff has no hunk; allowed: a unified diff with @@ -line,count +line,count @@ headers"),
    ("a replacement that changes nothing", _mutant(replace="'rate = alpha * dt / (h * h)'"),
     "the edit leaves fd_heat/solver.py unchanged; allowed: a replacement that differs from the text it replaces"),
]


@pytest.mark.parametrize(("what", "table", "message"), REFUSED_EDITS, ids=[c[0] for c in REFUSED_EDITS])
def test_an_edit_that_does_not_apply_is_one_line_before_anything_runs(what, table, message, tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text(STUDY + table)
    line = one_line_error(run("mutate", "s.toml", cwd=tmp_path, capfd=capfd))
    assert message in line, line
    assert not (tmp_path / "reports").exists()
    tally(EDITS, "rejected")


def test_an_unknown_mutant_name_lists_the_known_ones_entry_points_included(tmp_path, capfd, monkeypatch) -> None:
    """A plugin's entry point offers its mutants to the studies that run its package's solvers: listed among the
    known names; one of a package the study does not run is not; an entry point that raises is one line."""
    dist = tmp_path / "site"
    (dist / "fake_mutants-1.0.dist-info").mkdir(parents=True)
    (dist / "fake_mutants-1.0.dist-info" / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-mutants\n"
                                                                  "Version: 1.0\n")
    (dist / "fake_mutants-1.0.dist-info" / "entry_points.txt").write_text(
        "[pcverify.mutants]\nfd = fake_mutants:MUTANTS\nother = fake_mutants:OTHER\n")
    (dist / "fake_mutants.py").write_text(
        "MUTANTS = [{'name': 'from-entry-point', 'package': 'fd_heat', 'file': 'solver.py', 'find': 'h * h',\n"
        "            'replace': 'h * h * 2', 'breaks': 'a quarter of the rate'}]\n"
        "OTHER = lambda: [{'name': 'not-offered', 'package': 'json', 'file': 'decoder.py', 'find': 'x',\n"
        "                  'replace': 'y', 'breaks': 'another package'}]\n")
    monkeypatch.syspath_prepend(str(dist))
    (tmp_path / "s.toml").write_text(STUDY + _mutant())
    line = one_line_error(run("mutate", "s.toml", "--mutant", "m", "--mutant", "nope", cwd=tmp_path, capfd=capfd))
    assert line == "pcverify: error: --mutant 'nope' is not a mutant of study s; allowed: one of m, from-entry-point"
    tally(EDITS, "rejected")
    line = one_line_error(run("mutate", "default", "--mutant", "m", cwd=tmp_path, capfd=capfd))
    assert line == "pcverify: error: --mutant needs one study; allowed: a study name or a .toml file, not default"
    tally(EDITS, "rejected")
    (dist / "fake_broken.py").write_text("raise RuntimeError('broken plugin')\n")
    (dist / "fake_mutants-1.0.dist-info" / "entry_points.txt").write_text("[pcverify.mutants]\nfd = fake_broken:X\n")
    line = one_line_error(run("mutate", "s.toml", cwd=tmp_path, capfd=capfd))
    assert line == ("pcverify: error: entry point fd = 'fake_broken:X' of group pcverify.mutants failed to load: "
                    "RuntimeError: broken plugin")
    tally(EDITS, "rejected")


def test_a_unified_diff_applies_at_its_line_or_nearest_where_it_fits() -> None:
    source = "a\nb\nc\nb\nc\n"
    diff = "--- a/x.py\n+++ b/x.py\n@@ -4,2 +4,2 @@\n b\n-c\n+C\n"
    assert apply_diff(source, diff, "d") == "a\nb\nc\nb\nC\n"  # at its line, not at the first place it fits
    assert apply_diff(source, diff.replace("-4,2", "-1,2"), "d") == "a\nb\nC\nb\nc\n"  # shifted: the nearest
    with pytest.raises(MutantError, match="hunk 1"):
        apply_diff(source, "@@ -1 +1 @@\n-z\n+y\n", "d")
    tally(EDITS, "accepted", 3)
    count = Mutant("two", "solver.py", "x", package="fd_heat", find="h * h", replace="h ** 2", count=3)
    with pytest.raises(MutantError, match=r"occurs 2 times in fd_heat/solver.py; allowed: exactly count=3"):
        count.edited()
    tally(EDITS, "rejected")


def test_zz_mutants_tally() -> None:
    check_tally({TABLES: len(REFUSED_TABLES) + 3, EDITS: len(REFUSED_EDITS) + 7})
