"""Red team, study files read loosely: the whole file is parsed and checked before any cell runs, one line
per error with the allowed fields and types.  Misspelt or unknown keys (top level, group, claim), a string
where a list is expected, duplicate group ids, claim fields of the wrong type and a claim's `per`, `select`
or `metric` naming a column its table does not have are refused or reported, never ignored.  The command
runs in this process: a refusal needs no process of its own."""

from __future__ import annotations

import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from red_team import TALLY, check_tally, one_line_error, run, tally

from pcverify.harness.study.study import load_study
from pcverify.scene import SceneError

GROUP = 'scene = "bar-heat-faces"\nsolvers = ["skfem"]\nn = [2]\n'
BASE = f'name = "s"\n[[group]]\nid = "g"\n{GROUP}'
CLAIM = ('[[claim]]\nid = "c"\ntext = "exact"\ntable = "g-cells"\nmetric = "err.nodes.linf"\nreference = "analytic"\n'
         'tolerance = 1e-9\n')

REFUSED = [
    ("top-level key misspelt", 'name = "s"\ngrop = 1\n[[group]]\n' + GROUP,
     "grop is not a field of a study file; allowed: name, title, plugins, shipped_mutants, scene, group"),
    ("scene_param at top level", 'name = "s"\nscene_param = { t_max = 400.0 }\n[[group]]\n' + GROUP,
     "scene_param is not a field of a study file"),
    ("scene_param in a group", BASE + "scene_param = { t_max = 400.0 }\n",
     "group[1] (g): scene_param is not a field of [[group]] with analysis='table'; allowed: id, title, scene,"),
    ("box in a group", BASE + "box = { width = 0.02 }\n", "box is not a field of [[group]] with analysis='table'"),
    ("source in a group", BASE + "source = 1e6\n", "source is not a field of [[group]] with analysis='table'"),
    ("solver instead of solvers", 'name = "s"\n[[group]]\nscene = "bar-heat-faces"\nsolver = "skfem"\n',
     "solver is not a field"),
    ("quantities as one string", BASE.replace('id = "g"', 'id = "g"\nanalysis = "convergence"') +
     'quantities = "volume_mean"\n', "quantities='volume_mean' is not valid; allowed: a non-empty list of text"),
    ("duplicate group ids", BASE + '[[group]]\nid = "g"\n' + GROUP,
     "group[2] (g): id='g' is not valid; allowed: an id no other group has (group[1] has it)"),
    ("claim target naming nothing", BASE + CLAIM + 'target = "zero"\n',
     "claim[1] (c): target='zero' is not valid: unknown name 'zero'; allowed: an expression of width, height"),
    ("claim target as a list", BASE + CLAIM + 'target = [0.0]\n', "target=[0.0] is not valid; allowed: number or "),
    ("claim target of no reference", BASE + CLAIM + 'target = "reference:E_eff"\n',
     "claim[1] (c): target='reference:E_eff' is not valid; allowed: reference:NAME, NAME one of the scene's"),
    ("claim select as text", BASE + CLAIM + 'select = "solver == skfem"\n',
     "select='solver == skfem' is not valid; allowed: a table"),
    ("claim per as an empty list", BASE + CLAIM + 'per = []\n',
     "per=[] is not valid; allowed: text, or a non-empty list of them"),
    ("claim field misspelt", BASE + CLAIM + 'tolerence = 1.0\n',
     "tolerence is not a field of [[claim]]; allowed: id, text"),
    ("duplicate claim ids", BASE + CLAIM + CLAIM,
     "claim[2] (c): id='c' is not valid; allowed: an id no other claim has (claim[1]"),
    ("analysis unknown", BASE + 'analysis = "convergance"\n',
     "analysis='convergance' is not valid; allowed: one of table, convergence,"),
    ("probe unknown", BASE + 'analysis = "stability"\nprobe = "sweep"\n',
     "probe='sweep' is not valid; allowed: one of limit, map"),
    ("figures entry unknown", BASE + 'figures = ["render-4d"]\n',
     "figures='render-4d' is not valid; allowed: one of edge-profiles, render-3d"),
    ("unknown solver", BASE.replace('"skfem"', '"skfme"'), "solver='skfme' is unknown"),
    ("a value nested 100 000 deep", BASE + "v = " + "[" * 100_000 + "]" * 100_000 + "\n", "nested too deeply"),
]


@pytest.mark.parametrize("case, text, words", REFUSED, ids=[c[0] for c in REFUSED])
def test_a_bad_study_file_is_refused_before_any_cell_runs(case, text, words, tmp_path, capfd) -> None:
    (tmp_path / "s.toml").write_text(text)
    line = one_line_error(run("study", "s.toml", "--out", "out", cwd=tmp_path, capfd=capfd, seconds=60))
    assert words in line, line
    assert not (tmp_path / "out" / "cache").exists()  # nothing ran
    tally("study files", "rejected")


@pytest.mark.parametrize("claim, note", [
    ('per = "nn"\n', "column nn is not in table g-cells"),
    ('select = { solvr = "skfem" }\n', "column solvr is not in table g-cells"),
    ('metric = "err.nodes.l3"\n', "column err.nodes.l3 is not in table g-cells"),
])
def test_a_claim_naming_a_missing_column_says_so(claim, note, tmp_path, capfd) -> None:
    """A claim over a column the table does not have fails with the reason, never a silent single case or a
    pass."""
    metric = 'metric = "err.nodes.linf"\n'
    text = BASE + CLAIM.replace(metric, "" if "metric" in claim else metric)
    (tmp_path / "s.toml").write_text(text + claim)
    out = run("study", "s.toml", "--out", "out", cwd=tmp_path, capfd=capfd)
    assert out.returncode == 0, out.stderr[-1500:]
    verdicts = (tmp_path / "out" / "s" / "verdicts.csv").read_text()
    assert ",fail," in verdicts and note in verdicts, verdicts
    tally("study files", "accepted")


KEYS = st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789_", min_size=1, max_size=12)  # TOML bare keys


@settings(derandomize=True, database=None, deadline=None, max_examples=25,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(key=KEYS)
def test_any_unknown_group_key_is_refused(key, tmp_path_factory) -> None:
    allowed = {"id", "title", "scene", "scene_params", "solvers", "n", "refine", "solver_params", "sweep",
               "analysis", "serial", "figures", "vtu"}
    if key in allowed:
        TALLY["property group key allowed"] += 1
        return
    where = tmp_path_factory.mktemp("key")
    (where / "s.toml").write_text(BASE + f"{key} = 1\n")
    with pytest.raises(SceneError, match=re.escape(f"{key} is not a field of [[group]] with analysis='table'")):
        load_study(str(where / "s.toml"))
    TALLY["property group key refused"] += 1


def test_zz_study_file_tally() -> None:
    check_tally({"study files": 23})  # 20 refused files, 3 claims naming a missing column
    drawn = TALLY["property group key allowed"] + TALLY["property group key refused"]
    print(f"group keys drawn {drawn}, refused {TALLY['property group key refused']}")
    assert drawn == 25 and TALLY["property group key refused"] >= 20  # max_examples; a field name is rarely drawn
