"""Claim targets computed, not typed: "reference:NAME" and expressions of the case, resolved at load, judged per case,
and the shipped studies' computed targets equal to the numbers they replace."""

import dataclasses
import importlib
import math
from decimal import Decimal

import pandas as pd
import pytest

from pcverify.harness.judge.verdict import verdicts
from pcverify.harness.report.findings import target_text
from pcverify.harness.study.catalogue import entries, get_spec, register_scene
from pcverify.harness.study.shipped import study_files
from pcverify.harness.study.study import load_study
from pcverify.scene import Reference, SceneError

SCENE = "stick-slip-with-reference"  # the stick-slip scene with its cycle declared as the spec's reference
STUDY = """
name = "targets"
[[group]]
id = "cycle"
scene = "stick-slip-with-reference"
solvers = ["mca"]
n = [4, 6]
[[claim]]
id = "breakaway"
text = "at most mu_s N"
table = "cycle-cells"
per = "n"
metric = "spring_peak_N"
reference = "analytic"
target = "reference:spring_peak_N"
tolerance = 0.0
sense = "at-most"
[[claim]]
id = "above-kinetic"
text = "above mu_k N"
table = "cycle-cells"
per = "n"
metric = "spring_peak_N"
reference = "analytic"
target = "spring_peak_N * mu_kinetic / mu_static"
tolerance = 0.0
sense = "at-least"
"""


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    if SCENE not in entries():
        spec = get_spec("stick-slip")  # before the scene families held their references, the cycle's module did
        reference = spec.reference or Reference(scalars=lambda scene, summary: importlib.import_module(
            "pcverify.references.stick_slip").expected(scene))
        build = lambda p: dataclasses.replace(spec.build(p), name=SCENE)  # noqa: E731
        register_scene(dataclasses.replace(spec, name=SCENE, build=build, reference=reference), "tests/test_targets.py")
    path = tmp_path_factory.mktemp("targets") / "targets.toml"
    path.write_text(STUDY)
    return load_study(str(path))


def test_a_reference_target_is_the_scalar_of_the_scenes_reference(study) -> None:
    breakaway, kinetic = study.claims
    assert breakaway.targets == ((4, 1, pytest.approx(40.0)), (6, 1, pytest.approx(40.0)))
    assert [v for _, _, v in kinetic.targets] == [pytest.approx(30.0)] * 2


def test_a_case_is_judged_against_the_value_at_its_rows_level(study) -> None:
    cells = pd.DataFrame({"n": [4, 6], "refine": [1, 1], "status": ["ok", "ok"], "spring_peak_N": [37.0, 36.0],
                          "ref.spring_peak_N": [40.0, 40.0]})
    table = verdicts("targets", study.claims, {"cycle-cells": cells})
    assert table["target"].tolist() == [pytest.approx(40.0)] * 2 + [pytest.approx(30.0)] * 2
    assert table["target"].tolist()[:2] == pytest.approx(cells["ref.spring_peak_N"].tolist())  # as compare stored it
    assert table["target_from"].tolist()[:2] == ["reference:spring_peak_N"] * 2
    assert table["verdict"].tolist() == ["pass"] * 4
    record = table.iloc[0].to_dict() | {"metric": "spring_peak_N"}
    assert target_text(record).endswith("(reference:spring_peak_N)") and target_text(record).startswith("at most")


def test_a_case_whose_rows_span_levels_of_different_targets_is_not_judged(study) -> None:
    cells = pd.DataFrame({"n": [4, 6], "status": ["ok", "ok"], "spring_peak_N": [37.0, 36.0]})
    claim = dataclasses.replace(study.claims[0], per="", targets=((4, 1, 40.0), (6, 1, 41.0)))
    row = verdicts("targets", [claim], {"cycle-cells": cells}).iloc[0]
    assert row["verdict"] == "fail" and "no finite target" in row["note"]
    fits = pd.DataFrame({"quantity": ["q"], "order": [2.0]})  # a table of no level: every level's value is the same
    claim = dataclasses.replace(claim, metric="order", targets=((4, 1, 2.0), (6, 1, 2.0)))
    assert verdicts("targets", [claim], {"cycle-cells": fits})["verdict"].tolist() == ["pass"]


@pytest.mark.parametrize("target, words", [
    ("reference:spring_peek_N", "target='reference:spring_peek_N' is not valid; allowed: reference:NAME, NAME one of "
                                "the scene's reference scalars (spring_peak_N, spring_trough_N"),
    ("2 * mu", "target='2 * mu' is not valid: unknown name 'mu'; allowed: an expression of "),
    ("sqrt(", "target='sqrt(' is not valid (SyntaxError"),
    ("1 / (n - n)", "target='1 / (n - n)' is not valid (ZeroDivisionError"),
])
def test_a_bad_target_is_one_line_at_load_naming_the_claim_and_the_field(study, tmp_path, target, words) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace('"reference:spring_peak_N"', repr(target).replace("'", '"')))
    with pytest.raises(SceneError) as info:
        load_study(str(path))
    assert str(info.value).startswith("study file bad.toml: claim[1] (breakaway): ") and words in str(info.value)
    assert "\n" not in str(info.value)


def test_a_text_target_on_a_table_no_group_makes_is_refused(study, tmp_path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(STUDY.replace('table = "cycle-cells"', 'table = "elsewhere-cells"', 1))
    with pytest.raises(SceneError, match=r"claim\[1\] \(breakaway\): target='reference:spring_peak_N' is not valid; "
                                         r"allowed: a number \(no group makes the table\)"):
        load_study(str(path))


# The numbers the shipped studies' computed targets replace, as they were pasted: (study, claim) -> (the pasted
# text, the n its case is at, None: every level of its group).  A pasted value that was wrong shows as a difference
# beyond its last digit (listed in `WRONG` with the value the computation gives).
PASTED = {
    **{("elasticity", f"{c}-hooke-{q}"): (v, None) for c in ("continuum", "mca", "mca-cells")
       for q, v in (("E", "70e9"), ("nu", "0.33"))},
    ("elasticity", "mca-fracture-strength"): ("400e6", None),
    ("elasticity", "bpm-E"): ("70e9", None),
    ("elasticity", "bpm-fracture-strength"): ("400e6", None),
    ("elasticity", "mca-fracture-strength-k2"): ("200e6", None),  # sigma_c / k of the group's k = 2
    **{("elasticity", f"mca-{c}-strength"): ("400e6", None) for c in ("plastic", "degradation")},
    ("elasticity", "mca-plastic-yield"): ("300e6", None),
    ("elasticity", "mca-degradation-knee"): ("320e6", None),
    **{("elasticity", c): ("7e9", None) for c in ("mca-plastic-hardening", "mca-degradation-slope")},
    **{("contact-friction", f"sliding-mu-rough-seeds-{w}"): ("0.3477464829275686", None) for w in ("drive", "clamp")},
    ("contact-friction", "sliding-mu-regular-drive"): ("0.3477464829275686", None),
    ("contact-friction", "contact-pressure"): ("70e6", None),
    ("contact-friction", "heating-dissimilar-share"): ("0.41421356237309503", None),
    ("stick-slip", "stick-slip-breakaway"): ("40.0", None),
    ("stick-slip", "stick-slip-force-bounded"): ("40.8397", None),  # the rigid block's largest force from mu_s N
    ("elasticity", "continuum-axial-rod-theory"): ("41666.67", None),  # the closed forms in the claims' texts
    ("elasticity", "continuum-torsion-saint-venant"): ("23462.85", None),
    ("stick-slip", "stick-slip-breakaway-above-kinetic"): ("30.0", None),
    ("stick-slip", "stick-slip-breakaway-nearer-static"): ("35.0", None),
    **{("stick-slip", f"incline-stick-{a}"): ("0.0", None) for a in (15, 18, 20)},
    **{("elasticity", f"mca-nodes-bending-geometry-n{n}"): (v, n)
       for n, v in ((3, "0.224745"), (4, "0.105542"), (6, "0.039230"), (8, "0.020204"))},
    **{("elasticity", f"mca-cells-bending-geometry-n{n}"): (v, n)
       for n, v in ((3, "0.057191"), (4, "0.031754"), (6, "0.013987"), (8, "0.007843"))},
    ("continuum-heat", "paper-bulk-mesh-limit"): ("0.3333333333333333", None),  # the paper scene's bulk_median
    ("heat-particles", "paper-bulk-one-third"): ("0.3333333333333333", None),
    ("elasticity", "mca-rotational-frequency-n4"): ("11179.818", 4),  # the analytic chain at the group's krot
    ("elasticity", "mca-rotational-frequency-n6"): ("17859.730", 6),
    ("macromolecule", "top-mode-damping-ratio"): ("0.01", None),  # the value the claim selects
    ("macromolecule", "top-frequency-as-asked"): ("50.0", None),  # the solver's defaults
    ("macromolecule", "time-step-safety"): ("0.05", None),
    **{("macromolecule", f"stop-{what}-{scene}"): (v, None) for scene in ("paper", "faces")
       for what, v in (("halves-agree", "0.02"), ("deviation", "0.01"))},
    ("macromolecule", "lattice-particle-count"): ("16", 2),  # the paper's 16 particles, n^2 (3n - 2) at n = 2
    ("continuum-heat", "slab-source-fipy-offset"): ("0.1111111111111111", 2),  # FiPy's offset (a / L)^2 at n = 2
    # rho gamma V (L - a) / 2 at each n: 2800 kg/m^3, 3e6 /s, 0.3 m/s, L = 0.03 m, a = 0.01 / (n - 1)
    ("elasticity", "mca-damped-drag"): ({3: "31.5e6", 4: "33.6e6", 6: "35.28e6"}, None),
}
WRONG: dict[tuple[str, str], float] = {}


@pytest.mark.parametrize("name", sorted(study_files()))
def test_every_computed_target_of_a_shipped_study_is_the_number_it_replaces(name) -> None:
    computed = {(name, c.id): c for c in load_study(name).claims if isinstance(c.target, str)}
    assert set(computed) == {k for k in PASTED if k[0] == name}, "every computed target is listed in PASTED"
    for key, claim in computed.items():
        texts, n = PASTED[key]
        for level_n, _, value in claim.targets:
            pasted = texts[level_n] if isinstance(texts, dict) else texts  # one text per n, or one for all
            half_digit = 0.5 * 10.0 ** Decimal(pasted).as_tuple().exponent
            if n is None or level_n == n:
                want = WRONG.get(key, float(pasted))
                assert math.isfinite(value) and abs(value - want) <= max(half_digit, 1e-15 * abs(want)), (key, value)


SWEPT = """
name = "solver-targets"
[[group]]
id = "g"
scene = "bar-heat-faces"
solvers = ["macromolecule"]
n = [2]
solver_params = { p = 3.0 }
sweep = { damping_ratio = [0.0, 0.01] }
[[claim]]
id = "c"
text = "t"
table = "g-cells"
metric = "m"
reference = "theory"
target = "TARGET"
tolerance = 0.0
"""


@pytest.mark.parametrize("target, select, value", [
    ("p", "", 3.0),  # the group's own value of a solver parameter
    ("f_top / 2", "", 25.0),  # the solver's default
    ("damping_ratio", "select = { damping_ratio = 0.01 }", 0.01),  # swept: the value the claim selects
    ("density * conductivity", "", 2700.0 * 237.0),  # the scene material's constants
    ("damping_ratio", "", None),  # swept and not selected: no one value, an error
])
def test_a_target_names_the_solver_parameters_its_cases_share(tmp_path, target, select, value) -> None:
    path = tmp_path / "solver-targets.toml"
    path.write_text(SWEPT.replace("TARGET", target).replace('tolerance = 0.0', f"tolerance = 0.0\n{select}"))
    if value is None:
        with pytest.raises(SceneError, match=r"claim\[1\] \(c\): .*target.*damping_ratio"):
            load_study(str(path))
        return
    assert load_study(str(path)).claims[0].targets == ((2, 1, pytest.approx(value, rel=1e-15)),)
