"""A study plans only what runs: a solver whose task does not support the group's scene gets no cells, its reason
is one line per group (dry run, report), and a claim on those cells is judged as on skipped cells."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pcverify.harness.cli import main
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.harness.study.tasks import SOLVE, SupportsAnswerError, ask_supports

# fipy solves the transient bar; the macromolecule's hotness has no transient counterpart (it does not support
# the scene), so its cells are not planned
STUDY = textwrap.dedent('''
    name = "planning"
    title = "planning"

    [[group]]
    id = "transient"
    analysis = "table"
    scene = "bar-heat-faces"
    scene_params = { mode = "transient", t_end = 0.1, dt = 0.05 }
    solvers = ["fipy", "macromolecule"]
    n = [2, 3]

    [[claim]]
    id = "on-unplanned-allowed"
    text = "a claim on the macromolecule's cells, skips allowed"
    table = "transient-cells"
    select = { solver = "macromolecule" }
    metric = "unknowns"
    reference = "paper"
    target = 0
    tolerance = 1e9
    allow_skipped = true

    [[claim]]
    id = "on-unplanned"
    text = "a claim on the macromolecule's cells"
    table = "transient-cells"
    select = { solver = "macromolecule" }
    metric = "unknowns"
    reference = "paper"
    target = 0
    tolerance = 1e9

    [[claim]]
    id = "per-solver"
    text = "per solver, skips allowed"
    table = "transient-cells"
    per = "solver"
    metric = "unknowns"
    reference = "paper"
    target = 0
    tolerance = 1e9
    allow_skipped = true

    [[claim]]
    id = "every-solver"
    text = "over every solver's cells"
    table = "transient-cells"
    metric = "unknowns"
    aggregate = "max"
    reference = "paper"
    target = 0
    tolerance = 1e9
''')


def _study(tmp_path: Path) -> Path:
    path = tmp_path / "planning.toml"
    path.write_text(STUDY)
    return path


def test_a_solver_that_does_not_support_the_scene_is_not_planned(tmp_path, capsys) -> None:
    study = load_study(str(_study(tmp_path)))
    (group,) = study.groups
    assert {c.solver for c in group.cells} == {"fipy"} and len(group.cells) == 2
    (u,) = group.unplanned
    assert (u.solver, u.cells) == ("macromolecule", 2) and "transient" in u.reason
    assert main(["study", str(_study(tmp_path)), "--dry-run", "--json", "--out", str(tmp_path / "out")]) == 0
    (entry,) = json.loads(capsys.readouterr().out)
    assert [c["state"] for c in entry["cells"]] == ["to run", "to run"]
    assert entry["not_planned"] == [{"group": "transient", "solver": "macromolecule", "cells": 2,
                                     "reason": u.reason}]
    assert main(["study", str(_study(tmp_path)), "--dry-run", "--out", str(tmp_path / "out")]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [ln for ln in lines if ln.startswith("not planned:")] == [
        f"not planned: group transient, macromolecule (2 cells): {u.reason}"]


def test_claims_on_unplanned_cells_are_judged_as_on_skipped_ones(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    assert main(["study", str(_study(tmp_path)), "--json", "--out", str(out)]) == 0
    (entry,) = json.loads(capsys.readouterr().out)
    assert (entry["cells"], entry["done"]) == (2, 2)  # only fipy's cells ran
    verdicts = {(v["claim"], v["case"]): v for v in entry["verdicts"]}
    assert verdicts[("on-unplanned-allowed", "")]["verdict"] == "not-applicable"
    assert verdicts[("on-unplanned", "")]["verdict"] == "fail"
    assert "not planned" in verdicts[("on-unplanned", "")]["note"]
    assert verdicts[("per-solver", "solver=macromolecule")]["verdict"] == "not-applicable"
    assert verdicts[("per-solver", "solver=fipy")]["verdict"] == "pass"
    every = verdicts[("every-solver", "")]  # it would stand on fipy's cells alone: never a pass
    assert every["verdict"] == "fail" and "some of its cells are not planned" in every["note"]
    skipped = pd.read_csv(out / "planning" / "transient-skipped.csv")
    assert skipped[["solver", "status"]].values.tolist() == [["macromolecule", "not planned"]]


def test_a_supports_answer_is_checked_in_one_place() -> None:
    """(True or False, text) is a valid answer, numpy's booleans included; anything else is a
    SupportsAnswerError carrying the answer (its cell then fails naming it), and what supports raises
    propagates."""
    scene = make_scene("bar-heat-faces")

    class Answers:
        def __init__(self, answer):
            self.answer = answer

        def supports(self, scene):
            if isinstance(self.answer, Exception):
                raise self.answer
            return self.answer

    assert ask_supports(SOLVE, Answers((np.False_, "why")), scene) == (False, "why")
    assert ask_supports(SOLVE, Answers((True, "")), scene) == (True, "")
    for bad in ("yes", (1, "why"), (True, None), (True, "a", "b")):
        with pytest.raises(SupportsAnswerError) as info:
            ask_supports(SOLVE, Answers(bad), scene)
        assert info.value.answer == bad
    with pytest.raises(ZeroDivisionError):
        ask_supports(SOLVE, Answers(ZeroDivisionError("plugin")), scene)
