"""Rotational modes named as such (pcverify.solvers.modes.rotational) and their analytic frequency.

- the MCA bar at the calibration's cell (bar-modes n = 4, krot = 1e-4, the bound the calibration hits): its
  section-alternating rotations (rotational mass fraction 1.00) are `rotational`, never axial; f_axial is the
  real axial mode (near the continuum's 42.1 kHz, not the rotational 11.2 kHz); torsion is found although
  nine rotational modes lie below it;
- the rule itself: past one half of the mass norm in the rotations a mode is rotational whatever its parity,
  and a layout without rotations (scikit-fem) is left as it was;
- `mca_rotational_hz` reduces to 48 krot G / (rho a^2) deep inside a wide, long bar, matches the MCA's
  eigenproblem to the order-krot term it neglects, and is the number the elasticity study's claims pin.
"""

from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np
import pytest

import pcverify.solvers.modes as modes
from pcverify.harness.judge.tables import scalars
from pcverify.harness.study.catalogue import make_scene
from pcverify.harness.study.study import load_study
from pcverify.references.elastic import mca_rotational_hz
from pcverify.scene import Resolution
from pcverify.solvers.particles.mca.solver import Mca

STUDIES = Path(__file__).resolve().parents[1] / "harness" / "studies"
SHEAR = 70e9 / (2 * 1.33)  # duralumin, the bar-modes material
DENSITY = 2800.0


@pytest.fixture(scope="module")
def calibration_cell() -> dict:
    """The summary of the MCA on bar-modes n = 4 at krot = 1e-4 (the calibration's calibrated cell)."""
    return Mca().solve(make_scene("bar-modes"), Resolution(4), krot=1e-4).summary


def test_the_checkerboard_mode_of_a_small_bar_is_rotational_not_axial(calibration_cell):
    kinds = calibration_cell["mode_kinds"]
    share = np.asarray(calibration_cell["rotational_mass_fraction"])
    freqs = np.asarray(calibration_cell["frequencies_hz"])
    third = int(np.argmin(np.abs(freqs - 11179.6)))
    assert share[third] > 0.999 and kinds[third] == "rotational"
    # every mode mostly in the rotations is rotational, every other one is not
    assert [k == "rotational" for k in kinds] == list(share > modes.ROTATIONAL_SHARE)
    assert calibration_cell["f_rotational_hz"] == pytest.approx(11179.6, abs=0.1)


def test_f_axial_at_the_calibration_cell_is_the_axial_mode(calibration_cell):
    kinds = calibration_cell["mode_kinds"]
    f_axial = calibration_cell["f_axial_hz"]
    assert f_axial == pytest.approx(42626.7, abs=0.1)  # the continuum's (Q2, extrapolated) is 42 080 Hz
    axial = kinds.index("axial")
    assert calibration_cell["rotational_mass_fraction"][axial] < 0.01


def test_torsion_is_found_above_the_rotational_modes(calibration_cell):
    kinds = calibration_cell["mode_kinds"]
    assert calibration_cell["f_torsion_hz"] == pytest.approx(24989.1, abs=0.1)  # continuum: 23 592 Hz
    below = kinds[:kinds.index("torsion")]
    assert below.count("rotational") == 9 and below.count("bending-x") == below.count("bending-y") == 1
    # the asked eight modes of a continuum kind are all there, the rotational ones beside them
    assert sum(k != "rotational" for k in kinds) == 8 and kinds[-1] != "rotational"


def test_the_default_krot_reports_the_same_modes_as_before():
    """krot = 0.01 puts the rotational modes above 100 kHz: the eight modes are the ones before the rule (the
    last, half of the third bending pair, named by the pair's rule: bending-x first)."""
    summary = Mca().solve(make_scene("bar-modes"), Resolution(4)).summary
    assert summary["mode_kinds"] == ["bending-x", "bending-y", "torsion", "bending-x", "bending-y", "axial",
                                     "torsion", "bending-x"]
    assert "f_rotational_hz" not in summary


def test_the_rule_names_rotational_whatever_the_parity_and_leaves_translations_alone():
    assert modes.rotational("axial", {"axial": 0.0, "rotational": 0.51}) == "rotational"
    assert modes.rotational("torsion", {"axial": 0.0, "rotational": 0.9}) == "rotational"
    assert modes.rotational("axial", {"axial": 1.0, "rotational": 0.5}) == "axial"
    assert modes.rotational("bending-x", {"axial": 0.0}) == "bending-x"  # no rotations: scikit-fem's layout
    assert modes.lowest_of_each_kind(["bending-x", "rotational", "axial"], np.arange(3.0)) == {
        "f_bending_x_hz": 0.0, "f_rotational_hz": 1.0, "f_axial_hz": 2.0}
    summary = modes.kind_summary(["bending-x", "rotational", "axial"], np.arange(3.0))
    assert list(summary.pop("continuum_frequencies_hz")) == [0.0, 2.0]  # the rotational mode left out
    assert summary == modes.lowest_of_each_kind(["bending-x", "rotational", "axial"], np.arange(3.0))


def test_the_analytic_chain_reduces_to_the_interior_formula():
    a, krot = 1e-3, 1e-4
    interior = np.sqrt(48 * krot * SHEAR / (DENSITY * a**2)) / (2 * np.pi)
    assert mca_rotational_hz(SHEAR, DENSITY, a, krot, (10**6, 10**6, 2000)) == pytest.approx(interior, rel=1e-5)
    section = interior / np.sqrt(1 - (1 / 3 + 1 / 3) / 4)  # three spacings across: the half automata's share
    assert mca_rotational_hz(SHEAR, DENSITY, a, krot, (3, 3, 2000)) == pytest.approx(section, rel=1e-5)
    with pytest.raises(ValueError, match="cells="):
        mca_rotational_hz(SHEAR, DENSITY, a, krot, (0, 3, 9))


@pytest.mark.parametrize("n", [3, 4])
def test_the_mca_eigenproblem_matches_the_chain_to_the_order_krot_term(n):
    """The chain keeps the section's rotation uniform: the eigenproblem may do better, by a share of order krot."""
    cells = (n - 1, n - 1, 3 * (n - 1))
    for krot in (1e-4, 1e-3):
        found = Mca().solve(make_scene("bar-modes"), Resolution(n), krot=krot).summary["f_rotational_hz"]
        chain = mca_rotational_hz(SHEAR, DENSITY, 0.01 / (n - 1), krot, cells)
        assert -3 * krot < found / chain - 1 < 0


def test_the_elasticity_claims_pin_the_chain_and_allow_three_krot():
    study = tomllib.loads((STUDIES / "elasticity.toml").read_text())
    group = next(g for g in study["group"] if g["id"] == "mca-rotational-modes")
    krot = group["solver_params"]["krot"]
    claims = [c for c in study["claim"] if c["metric"] == "f_rotational_hz"]
    assert sorted(c["select"]["n"] for c in claims) == sorted(group["n"])
    resolved = {c.id: c.targets for c in load_study("elasticity").claims}  # the targets the study computes
    for claim in claims:
        n = claim["select"]["n"]
        chain = mca_rotational_hz(SHEAR, DENSITY, 0.01 / (n - 1), krot, (n - 1, n - 1, 3 * (n - 1)))
        assert dict(((level, refine), v) for level, refine, v in resolved[claim["id"]])[n, 1] == pytest.approx(
            chain, rel=1e-12)
        assert claim["tolerance"] == pytest.approx(3 * krot * chain, rel=1e-3)
    mutants = tomllib.loads((STUDIES / "elasticity.mutants.toml").read_text())["mutant"]
    halved = next(m for m in mutants if m["name"] == "mca-rotational-inertia-halved")
    assert set(halved["expect"]) == {c["id"] for c in claims}


def test_the_continuum_spectrum_leaves_out_the_rotational_modes(calibration_cell):
    """The modes a continuum has, in order: bending pair, torsion, ..., however many rotational modes lie between
    (the elasticity study's claim on fc3_hz reads the third)."""
    kinds = calibration_cell["mode_kinds"]
    spectrum = calibration_cell["continuum_frequencies_hz"]
    assert len(spectrum) == 8
    assert list(spectrum) == [f for f, k in zip(calibration_cell["frequencies_hz"], kinds, strict=True)
                              if k != "rotational"]
    assert spectrum[2] == pytest.approx(calibration_cell["f_torsion_hz"], rel=1e-15)


def test_a_cells_table_spreads_both_spectra():
    """f<k>_hz every mode, fc<k>_hz the modes of a continuum kind: the columns claims and calibrations read."""
    row = scalars({"summary": {"frequencies_hz": [1.0, 2.0, 3.0], "continuum_frequencies_hz": [1.0, 3.0],
                               "mode_kinds": ["bending-x", "rotational", "axial"]}})
    assert {k: v for k, v in row.items() if k.endswith("_hz")} == {"f1_hz": 1.0, "f2_hz": 2.0, "f3_hz": 3.0,
                                                                  "fc1_hz": 1.0, "fc2_hz": 3.0}
