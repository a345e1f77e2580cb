"""The study file's schema: one walk checks a document against a declaration, each kind of field refuses what
it must in one dialect (where: field=value is not valid; allowed: ...), and a new kind of table is one
declaration."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from pcverify.harness.study.analyses import REGISTRIES
from pcverify.harness.study.schema import CALIBRATION, NAME, STUDY, TABLES, Field, Table, check, check_value
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.studyfile import read_study_document
from pcverify.scene import SceneError, is_real

TOY = Table("[[toy]]", (
    Field("id", "text", unique=True, required=True),
    Field("count", "int", low=2, high=10),
    Field("weight", "real", low=0.0, low_open=True),
    Field("colour", "text", choices=("red", "blue")),
    Field("label", "text", hint=NAME.hint, pattern=NAME.pattern),
    Field("sizes", "int", low=1, high=9, shape="value or list"),
    Field("point", "real", shape="list", min_items=3, max_items=3),
    Field("shape", "record", table=Table("shape", (Field("kind", "text", required=True), Field("side", "real")))),
    Field("params", "table"),
), key="id")
DOCUMENT = Table("a toy file", (Field("title", "text"), Field("toy", "tables", table=TOY, min_items=0)))


def _error(doc: dict, table: Table = DOCUMENT, registries: dict | None = None) -> str:
    with pytest.raises(SceneError) as info:
        check(doc, table, "study file t.toml", registries)
    message = str(info.value)
    assert "\n" not in message
    return message


def _toy(**fields) -> dict:
    return {"toy": [{"id": "a"} | fields]}


def test_a_new_table_needs_only_its_declaration() -> None:
    """TOY and DOCUMENT above are the whole declaration: a good document passes, a bad row is named by its
    number and id."""
    check(_toy(count=3, weight=0.5, colour="red", label="x-1", sizes=[1, 2], point=[0, 1.5, 2],
               shape={"kind": "cube", "side": 1}, params={"any": [1, "x"]}), DOCUMENT, "study file t.toml")
    doc = {"toy": [{"id": "a"}, {"id": "b", "count": 11}]}
    assert _error(doc) == "study file t.toml: toy[2] (b): count=11 is not valid; allowed: integer in [2, 10]"


@pytest.mark.parametrize("value", [1, 11, 2.0, True, "3"])
def test_an_int_field_takes_integers_in_its_range_only(value) -> None:
    assert _error(_toy(count=value)).endswith(f"count={value!r} is not valid; allowed: integer in [2, 10]")


@pytest.mark.parametrize("value", [0, 0.0, -1.5, True, False, math.nan, math.inf, -math.inf, "1.0", None])
def test_a_real_field_takes_finite_numbers_in_its_range_and_never_a_bool(value) -> None:
    assert _error(_toy(weight=value)).endswith("is not valid; allowed: number in (0, inf)")


def test_an_int_range_is_written_in_whole_numbers() -> None:
    with pytest.raises(SceneError, match=re.escape("here: seed=True is not valid; allowed: integer in [0, "
                                                   "2147483647]")):
        check_value(True, CALIBRATION.field("seed"), "here")


def test_the_finite_real_predicate() -> None:
    assert all(is_real(v) for v in (0, 1, -2.5, 1e308, np.float64(1.0), np.int64(3)))
    assert not any(is_real(v) for v in (True, False, np.bool_(True), math.nan, math.inf, 10**400, "1", None, [1]))


def test_a_choice_names_its_choices() -> None:
    assert _error(_toy(colour="green")) == ("study file t.toml: toy[1] (a): colour='green' is not valid; allowed: "
                                            "one of red, blue")


@pytest.mark.parametrize("value", ["", ".hidden", "..", "a/b", "x" * 81, 7])
def test_a_text_pattern_says_what_it_allows(value) -> None:
    assert _error(_toy(label=value)).endswith("is not valid; allowed: 1 to 80 letters, digits, '.', '_' or '-', "
                                              "starting with a letter or digit")


def test_lists_of_values() -> None:
    """A value or a list (the bad entry is shown); a list of exactly three; a string is one value, never its
    characters."""
    assert _error(_toy(sizes=[1, 0])).endswith("sizes=0 is not valid; allowed: integer in [1, 9], or a non-empty "
                                               "list of them")
    assert _error(_toy(sizes=[])).endswith("sizes=[] is not valid; allowed: integer in [1, 9], or a non-empty list "
                                           "of them")
    assert _error(_toy(point=[0, 1])).endswith("point=[0, 1] is not valid; allowed: a list of 3 values, each number")
    assert _error(_toy(point=[0, 1, math.nan])).endswith("point=nan is not valid; allowed: a list of 3 values, each "
                                                         "number")
    assert "sizes='3'" in _error(_toy(sizes="3"))


def test_a_nested_table_is_walked_with_its_path() -> None:
    assert _error(_toy(shape={"kind": "cube", "side": True})) == (
        "study file t.toml: toy[1] (a): shape.side=True is not valid; allowed: number")
    assert _error(_toy(shape={"side": 1.0})) == (
        "study file t.toml: toy[1] (a): shape.kind is missing; allowed: text")
    assert _error(_toy(shape={"kind": "c", "sides": 1})) == (
        "study file t.toml: toy[1] (a): shape.sides is not a field of shape; allowed: kind, side")
    assert _error(_toy(shape="cube")).endswith("shape='cube' is not valid; allowed: a table { kind, side }")
    assert _error(_toy(params=[1])).endswith("params=[1] is not valid; allowed: a table { key = value, ... }")


def test_a_required_field_missing_and_an_unknown_key_with_the_allowed_ones() -> None:
    assert _error({"toy": [{"count": 3}]}) == "study file t.toml: toy[1]: id is missing; allowed: text"
    assert _error(_toy(cuont=3)) == ("study file t.toml: toy[1] (a): cuont is not a field of [[toy]]; allowed: id, "
                                     "count, weight, colour, label, sizes, point, shape, params")
    assert _error({"tiitle": "x"}) == ("study file t.toml: tiitle is not a field of a toy file; allowed: title, toy")


@pytest.mark.parametrize("value", [1, "x", {"id": "a"}, [1], [{"id": "a"}, "b"]])
def test_a_list_of_tables_of_the_wrong_type_is_refused(value) -> None:
    assert _error({"toy": value}).endswith("is not valid; allowed: a list of [[toy]] tables")


def test_a_unique_field_names_the_row_that_has_it() -> None:
    assert _error({"toy": [{"id": "a"}, {"id": "b"}, {"id": "a"}]}) == (
        "study file t.toml: toy[3] (a): id='a' is not valid; allowed: an id no other toy has (toy[1] has it)")


def test_a_variant_field_adds_the_fields_of_its_value() -> None:
    """A group's analysis adds that analysis's options (the registry is given to the walk by name)."""
    registries = REGISTRIES
    group = {"scene": "bar-heat-faces", "solvers": "skfem"}
    check({"group": [group | {"analysis": "stability", "probe": "map"}]}, STUDY, "study file s.toml", registries)
    assert _error({"group": [group | {"probe": "map"}]}, STUDY, registries).startswith(
        "study file t.toml: group[1]: probe is not a field of [[group]] with analysis='table'; allowed: id, title")
    assert _error({"group": [group | {"analysis": "stability", "probe": "mop"}]}, STUDY, registries).endswith(
        "probe='mop' is not valid; allowed: one of limit, map")


def test_a_calibration_error_names_every_level() -> None:
    cell = {"scene": "bar-heat-faces", "metric": "q", "reference": {"solver": "skfem", "n": 1}}
    doc = {"calibration": [{"id": "cal", "solver": "mca", "parameter": [{"name": "krot", "low": 1, "high": 2}],
                            "calibrate": [cell | {"reference": "analytic"}, cell], "validate": [cell]}]}
    assert _error(doc, STUDY) == ("study file t.toml: calibration[1] (cal): calibrate[2]: reference.n=1 is not "
                                  "valid; allowed: integer in [2, 1000]")


def test_every_shipped_study_fits_the_schema_and_every_table_is_a_top_level_key() -> None:
    registries = REGISTRIES
    for path in study_files().values():
        check(read_study_document(path), STUDY, f"study file {path.name}", registries)
    assert set(TABLES) <= {f.name for f in STUDY.fields}
