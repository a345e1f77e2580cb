"""The contact-friction study's mutant catalogue (harness/studies/contact-friction.mutants.toml): defects a contact,
friction and frictional-heating implementation really has.  Every mutant applies to the code as it is (its find
text occurs once, the edit is Python and changes code) and names the claims it expects to be caught by, which the
study has.  The outside audit's defect -- the friction's reaction on the base dropped, Newton's third law
broken -- run in a mutant's process (the overlay `pcverify mutate` uses): the friction law's own mu_dr and the
energy balance do not see it, mu at the clamp and the balance of the external forces do.  The whole catalogue
runs with `pcverify mutate contact-friction` (tox -e mutate)."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from pcverify.harness.run.mutation import overlaid
from pcverify.harness.study.mutants import Mutant, catalogue
from pcverify.harness.study.study import load_study

STUDY = Path(__file__).resolve().parent.parent / "harness" / "studies" / "contact-friction.toml"


@pytest.fixture(scope="module")
def mutants() -> list[Mutant]:
    return catalogue([], STUDY, {"pcverify"})


def test_every_catalogued_mutant_applies_and_names_the_claims_of_the_study(mutants) -> None:
    claims = {c.id for c in load_study(str(STUDY)).claims}
    assert len(mutants) >= 8 and len({m.name for m in mutants}) == len(mutants)
    assert {m.name for m in mutants} >= {"friction-reaction-dropped", "contact-stiffness-9pct", "friction-sign",
                                         "mu1-applied-twice", "roughness-factor-dropped", "heat-all-to-slider",
                                         "heating-power-abs-v", "normal-force-one-side", "regularisation-speed-10x"}
    for m in mutants:
        source, edited = m.edited()  # MutantError unless the find text occurs exactly once
        assert m.changes_code(source, edited), m.name
        compile(edited, m.file, "exec")
        assert m.breaks and m.expect and set(m.expect) <= claims, (m.name, set(m.expect) - claims)


def test_the_dropped_reaction_passes_the_laws_own_numbers_and_fails_the_reactions(mutants, tmp_path) -> None:
    """In the mutant's process (contact.py edited, the mechanics kernels recompiled into a copy of the numba
    cache) block-sliding at n = 4 still gives the law's mu_dr = 0.3 and a closed energy balance, but its clamp
    holds no tangential force and the drive's 30 N has no counterpart: Newton's third law misses by mu1 F_N."""
    (m,) = [m for m in mutants if m.name == "friction-reaction-dropped"]
    _, edited = m.edited()
    source = tmp_path / "contact.py"
    source.write_text(edited, encoding="utf-8")
    cache = os.environ.get("NUMBA_CACHE_DIR")
    if cache and Path(cache).is_dir():  # the kernels that do not reach contact.py load as compiled
        shutil.copytree(cache, tmp_path / "numba", dirs_exist_ok=True)
    run = ["run", "block-sliding", "--solver", "mca", "--n", "4", "--set", "duration=2e-4", "--json"]
    code, timed_out = overlaid(m.module(), source, m.path(), [run], tmp_path, 600.0)
    assert (code, timed_out) == (0, False), (tmp_path / "run.log").read_text()[-2000:]
    (result,) = json.loads((tmp_path / "outcome.json").read_text())["results"]
    out = result["json"]
    s = out["summary"]
    assert result["exit"] == 0 and out["status"] == "ok", out["reason"]
    assert s["mu_dr_error"] < 1e-4 and s["energy_balance_error"] < 1e-5  # the law's bookkeeping is blind to it
    assert s["mu_drive"] == pytest.approx(0.3, rel=1e-3)  # the slider still feels the friction
    assert abs(s["mu_clamp"]) < 1e-3  # the base does not
    assert s["newton_error"] == pytest.approx(0.3, rel=1e-2)  # the drive's mu1 F_N, unbalanced
