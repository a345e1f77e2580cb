"""Red team, the thermal constants of dissimilar blocks (frictional-heating's base_conductivity and
base_heat_capacity, the Contact part's fields): out of range, not a number, given to a scene that has no
friction heating to use them, or to the flux variant the continuum solvers take as one material -- each is one
line naming the parameter and what is allowed, never a run whose reference or whose heat silently ignores the
lower block's own constants."""

from __future__ import annotations

import json

import pytest
from red_team import TALLY, tally

from pcverify.harness.cli import main
from pcverify.scene import Contact, SceneError


def _error_line(capsys) -> str:
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("pcverify: error: "), lines
    return lines[0]


@pytest.mark.parametrize("settings, words", [
    (("base_conductivity=0",), "base_conductivity=0"),
    (("base_conductivity=-60.5",), "base_conductivity=-60.5"),
    (("base_conductivity=1e5",), "base_conductivity=100000"),
    (("base_conductivity=nan",), "base_conductivity=nan"),
    (("base_heat_capacity=0",), "base_heat_capacity=0"),
    (("base_heat_capacity=inf",), "base_heat_capacity=inf"),
    (("source=flux", "base_conductivity=60.5"), "base_conductivity=60.5 is not allowed with source='flux'"),
    (("source=flux", "base_heat_capacity=1750"), "base_heat_capacity=1750"),
])
def test_a_bad_constant_of_the_lower_block_is_one_error_line(settings, words, capsys) -> None:
    args = ["run", "frictional-heating", "--solver", "skfem" if "source=flux" in settings else "mca", "--n", "4"]
    for s in settings:
        args += ["--set", s]
    assert main(args) == 2
    line = _error_line(capsys)
    assert words in line and "allowed" in line, line
    assert "base_" in line and ("source='friction'" in line or "(0, " in line), line
    tally("dissimilar-blocks", "rejected")


def test_thermal_constants_of_a_contact_without_heating_are_refused() -> None:
    with pytest.raises(SceneError) as err:
        Contact(axis="z", position=0.015, base_conductivity=60.5)
    assert str(err.value).startswith("base_conductivity=60.5 is not allowed without heating; allowed:")
    tally("dissimilar-blocks", "rejected")


def test_a_continuum_solver_does_not_take_the_dissimilar_scene_as_one_material(capsys) -> None:
    """Accepted: the friction variant with the lower block's constants is MCA's (the continuum heat solvers
    decline a contact scene, so none runs it as one material)."""
    code = main(["run", "frictional-heating", "--solver", "fipy", "--n", "4", "--set", "base_conductivity=60.5",
                 "--json"])
    out = json.loads(capsys.readouterr().out)
    assert code == 0 and out["status"] == "skipped" and "contact" in out["reason"], out
    assert out["errors"] == {}
    tally("dissimilar-blocks", "accepted")


def test_zz_dissimilar_blocks_tally() -> None:
    expected = {"dissimilar-blocks": 10}
    for family, count in expected.items():
        tried, rejected, accepted = (TALLY[f"{family} {k}"] for k in ("tried", "rejected", "accepted"))
        print(f"\n{family}: tried {tried}, rejected cleanly {rejected}, accepted correctly {accepted}")
        assert tried == rejected + accepted == count, family
