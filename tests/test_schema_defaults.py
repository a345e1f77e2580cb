"""Defaults applied once: the schema's check fills every declared default into the document it returns, and the
readers take them from there, so what a minimal study runs is what the schema (and docs/study-files.md) says."""

import dataclasses
import math
import re
from pathlib import Path

import pytest

from pcverify.harness.judge import group_tables
from pcverify.harness.report import group_figures
from pcverify.harness.study import analyses, calibspec, catalogue, claims, study, studyfile
from pcverify.harness.study.analyses import REGISTRIES
from pcverify.harness.study.calibspec import Calibration
from pcverify.harness.study.schema import (
    CALIBRATION,
    CALIBRATION_CELL,
    CLAIM,
    GROUP,
    PARAMETER,
    REFERENCE,
    TABLES,
    check,
)
from pcverify.harness.study.study import load_study

MINIMAL = """
[[group]]
id = "plain"
scene = "bar-heat-faces"
solvers = ["skfem"]
[[group]]
id = "timed"
scene = "bar-heat-faces"
solvers = ["skfem"]
analysis = "timing"
[[claim]]
id = "c"
text = "exact"
table = "plain-cells"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
[[calibration]]
solver = "mca"
[[calibration.parameter]]
name = "krot"
low = 0.01
high = 0.1
[[calibration.calibrate]]
scene = "bar-heat-faces"
metric = "nodes.l2"
reference = "analytic"
[[calibration.validate]]
scene = "bar-heat-patch"
metric = "bulk_median"
reference = { solver = "skfem" }
"""


def _declared(table) -> dict[str, object]:
    return {f.name: f.default for f in table.fields if f.default is not None}


@pytest.fixture(scope="module")
def minimal(tmp_path_factory) -> study.Study:
    path = tmp_path_factory.mktemp("defaults") / "minimal.toml"
    path.write_text(MINIMAL)
    return load_study(str(path))


def test_a_minimal_group_runs_the_schemas_defaults(minimal) -> None:
    plain, timed = minimal.groups
    assert {c.n for c in plain.cells} == set(GROUP.field("n").default)
    assert {c.refine for c in plain.cells} == set(GROUP.field("refine").default)
    assert plain.analysis == GROUP.field("analysis").default
    assert {c.repeats for c in timed.cells} == {GROUP.field("repeats").default}
    options = {k: plain.options[k] for k in ("vtu", "figures", "figure_y")}
    assert options == {k: GROUP.field(k).default for k in options}


def test_a_minimal_claim_has_the_schemas_defaults(minimal) -> None:
    claim = minimal.claims[0]
    for name, default in _declared(CLAIM).items():
        value = getattr(claim, name)
        assert (list(value) if isinstance(value, tuple) else value) == default, name


def test_a_minimal_calibration_has_the_schemas_defaults(minimal) -> None:
    cal = minimal.calibrations[0]
    for name, default in _declared(CALIBRATION).items():
        if name in calibspec.OPTIONS:
            assert getattr(cal, name) == default, name
    assert math.isnan(cal.tolerance) and CALIBRATION.field("tolerance").default is None
    assert cal.parameters[0].log == PARAMETER.field("log").default
    cell = cal.calibrate[0]
    assert (cell.n, cell.refine, cell.error) == tuple(CALIBRATION_CELL.field(k).default for k in ("n", "refine",
                                                                                                   "error"))
    assert cal.validate[0].reference.refine == (REFERENCE.field("refine").default,)


def test_the_check_fills_every_declared_default_and_leaves_the_document_read_as_it_was() -> None:
    row = {"id": "g", "scene": "bar-heat-faces", "solvers": "skfem"}
    normal = check(row, GROUP, "here", {"analyses": {"table": ()}, "figures": ()})
    assert normal == row | _declared(GROUP) and row == {"id": "g", "scene": "bar-heat-faces", "solvers": "skfem"}
    normal["figures"].append("x")
    assert GROUP.field("figures").default == []  # a copy: no reader can change the declaration


def test_no_reader_of_the_spec_repeats_a_default_the_schema_declares() -> None:
    options = [f for fields in REGISTRIES["analyses"].values() for f in fields]
    defaults = {(f.name, repr(f.default)) for t in [*TABLES.values(), CALIBRATION_CELL, PARAMETER, REFERENCE]
                for f in [*t.fields, *options] if f.default is not None}
    for module in (study, studyfile, claims, calibspec, analyses, catalogue, group_tables, group_figures):
        text = Path(module.__file__).read_text(encoding="utf-8")
        for name, default in defaults:
            literal = "|".join(re.escape(d) for d in {default, default.replace("'", '"')})
            pattern = rf"\.get\(\s*['\"]{re.escape(name)}['\"]\s*,\s*(?:{literal})\s*\)"
            assert not re.search(pattern, text), (module.__name__, name, default)
    assert {f.name for f in dataclasses.fields(Calibration)} >= set(calibspec.OPTIONS)
