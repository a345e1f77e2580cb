"""Resolution-coupled parameters: a numeric scene or solver parameter given as an expression of n, refine, a
and h, evaluated per cell, checked like any value, in the cell's key and shown in its tables."""

import json

import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.study.expressions import evaluate, resolve, variables
from pcverify.harness.study.study import load_study
from pcverify.scene import Param, SceneError

AT_3 = variables(3, 2, 0.005)  # n = 3 on the 10 mm bar: a = 5 mm; refine 2: h = 2.5 mm


def test_the_grammar():
    assert AT_3 == {"n": 3.0, "refine": 2.0, "a": 0.005, "h": 0.0025}
    assert evaluate("delta", "3 * h", AT_3) == pytest.approx(0.0075)
    assert evaluate("dt", "0.1 * sqrt(a) / (n - 1)**2 + max(h, 1e-3)", AT_3) == pytest.approx(
        0.1 * 0.005**0.5 / 4 + 0.0025)
    assert evaluate("x", "-2e-3", AT_3) == -0.002


@pytest.mark.parametrize("text, word", [
    ("3 * x", "unknown name 'x'"),
    ("__import__('os').system('true')", "Call is not allowed"),
    ("h if n else a", "IfExp is not allowed"),
    ("3 *", "SyntaxError"),
    ("1 / (n - 3)", "ZeroDivisionError"),
    ("10 ** 400", "an exponent beyond 64"),
    ("h" + " + h" * 100, "at most 200 characters"),
    ("log(-1)", "ValueError"),
])
def test_bad_expressions_are_one_line_naming_the_parameter(text, word):
    with pytest.raises(SceneError) as exc:
        evaluate("delta", text, AT_3)
    message = str(exc.value)
    assert message.startswith("delta=") and word in message and "\n" not in message
    assert "allowed: an expression of n, refine, a, h" in message


def test_only_numeric_parameters_take_expressions_and_ints_round():
    specs = (Param("delta", 1.0, "m", low=0.0), Param("label", "3 * h", "", "text stays text", kind=str),
             Param("count", 2, "", "integer", low=1, high=100, kind=int))
    values, expressions = resolve({"delta": "3 * h", "label": "3 * h", "count": "4 * refine"}, specs, AT_3)
    assert values == {"delta": pytest.approx(0.0075), "label": "3 * h", "count": 8}
    assert isinstance(values["count"], int) and expressions == {"delta": "3 * h", "count": "4 * refine"}


STUDY = """
name = "coupled"
[[group]]
id = "faces"
title = "transient faces, a step of 10 s per metre of h and a direct-solve bound of 10 n unknowns"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.2, dt = "10 * h" }
solvers = ["skfem"]
n = [2, 3, 4]
solver_params = { direct_max_unknowns = "10 * n" }
"""


def test_a_study_with_coupled_parameters(tmp_path, capsys):
    path = tmp_path / "coupled.toml"
    path.write_text(STUDY)
    study = load_study(str(path))
    cells = study.groups[0].cells
    assert [c.scene.conduction.dt for c in cells] == pytest.approx([0.1, 0.05, 0.1 / 3])
    assert [dict(c.solver_params)["direct_max_unknowns"] for c in cells] == [20, 30, 40]
    assert dict(cells[0].expressions) == {"direct_max_unknowns": "10 * n", "scene.dt": "10 * h"}
    assert main(["study", str(path), "--out", str(tmp_path / "out"), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)[0]
    assert out["failed"] == 0 and out["cells"] == 3
    table = pd.read_csv(tmp_path / "out" / "coupled" / "faces-cells.csv")
    assert table["params"].tolist() == [f"direct_max_unknowns={k} (= 10 * n)" for k in (20, 30, 40)]
    assert table["scene_params"].str.contains(r"dt=0\.1 \(= 10 \* h\)", regex=True).iloc[0]
    levels = pd.read_csv(tmp_path / "out" / "coupled" / "faces-levels.csv")
    # one sequence: the expression, not its value, is what the levels share
    assert set(levels["params"]) == {"direct_max_unknowns=10 * n"} and levels["resolved"].nunique() == 3
    fits = pd.read_csv(tmp_path / "out" / "coupled" / "faces-fits.csv")
    assert len(fits[fits["quantity"] == "nodes.l2"]) == 1


def test_the_expression_is_part_of_the_cell_key(tmp_path, capsys):
    path = tmp_path / "coupled.toml"
    path.write_text(STUDY)
    literal = tmp_path / "literal.toml"
    literal.write_text(STUDY.replace('name = "coupled"', 'name = "literal"').replace('"10 * n"', "30")
                       .replace("n = [2, 3, 4]", "n = [3]"))
    assert main(["study", str(path), "--dry-run", "--json"]) == 0
    cells = json.loads(capsys.readouterr().out)[0]["cells"]
    keys = {c["cell"].split(" n=")[1][0]: c["key"] for c in cells}
    assert "direct_max_unknowns=30 (= 10 * n)" in cells[1]["cell"] and "dt=0.05 (= 10 * h)" in cells[1]["cell"]
    assert main(["study", str(literal), "--dry-run", "--json"]) == 0
    other = json.loads(capsys.readouterr().out)[0]["cells"][0]["key"]
    assert other != keys["3"]  # direct_max_unknowns = 30 either way, but written otherwise


@pytest.mark.parametrize("line, words", [
    ('solver_params = { direct_max_unknowns = "10 * m" }', ["group[1] (faces)", "direct_max_unknowns='10 * m'",
                                                            "unknown name 'm'"]),
    ('solver_params = { direct_max_unknowns = "1e9 * n" }', ["direct_max_unknowns=", "out of range",
                                                             "given as direct_max_unknowns = '1e9 * n' at n=2"]),
])
def test_a_bad_expression_in_a_study_is_one_line(tmp_path, capsys, line, words):
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace('solver_params = { direct_max_unknowns = "10 * n" }', line))
    assert main(["study", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(w in err for w in words), err


@pytest.mark.parametrize("line, words", [
    # an extent of the box from an expression: a and h would come from another box than the cell's
    ('width = "0.005 + 0 * n"', ["scene parameter width = '0.005 + 0 * n' is an expression of the "
                                                    "resolution and sets the box (at n=2, refine=1)",
                                                    "allowed: a number for a parameter of the box's extent"]),
    ('width = "a"', ["scene parameter width = 'a' is an expression", "sets the box"]),
    # a scene parameter out of range from an expression names the expression and the resolution
    ('t_max = "-1 * n"', ["t_max=-2", "out of range", "t_max = '-1 * n' at n=2, refine=1"]),
])
def test_a_scene_expression_that_sets_the_box_or_leaves_its_range_is_one_line(tmp_path, capsys, line, words):
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace('dt = "10 * h" }', f'dt = "10 * h", {line} }}'))
    assert main(["study", str(path), "--dry-run"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and all(w in err for w in words), err
