"""The clamped bar's closed-form axial and torsional frequencies (pcverify.references.elastic), the targets the
elasticity and calibration studies judge the continuum reference and the mode classifier with.

- Saint-Venant's torsion constant J = beta b c^3 reproduces the classical table of beta (Timoshenko and Goodier,
  Theory of Elasticity, table of torsion of rectangular bars) and its limit 1/3 for a thin strip; the section's
  orientation does not matter;
- elementary rod theory is c / (4 L), c = sqrt(E / rho);
- bad inputs are refused naming them;
- the studies' targets are these functions at the default bar (computed in the elasticity study, typed in the
  calibration study, whose tables have no group to compute them in).
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest

from pcverify.harness.study.study import load_study
from pcverify.references.elastic import rod_axial_hz, saint_venant_torsion_hz
from pcverify.scene import DURALUMIN

STUDIES = Path(__file__).resolve().parents[1] / "harness" / "studies"
SHEAR = DURALUMIN.youngs_modulus / (2 * (1 + DURALUMIN.poisson_ratio))
RHO = DURALUMIN.density
# beta of J = beta b c^3 against b / c, to the table's three digits
BETA_TABLE = {1.0: 0.141, 1.5: 0.196, 2.0: 0.229, 3.0: 0.263, 5.0: 0.291, 10.0: 0.312}


def _beta(ratio: float) -> float:
    """beta recovered from the frequency of a bar with sides ratio x 1 (I_p and L known)."""
    f = saint_venant_torsion_hz(SHEAR, RHO, ratio, 1.0, 1.0)
    polar = ratio * (ratio**2 + 1.0) / 12.0
    return (4.0 * f) ** 2 * RHO * polar / (SHEAR * ratio)


@pytest.mark.parametrize(("ratio", "beta"), sorted(BETA_TABLE.items()))
def test_the_torsion_constant_is_saint_venants(ratio, beta):
    assert _beta(ratio) == pytest.approx(beta, abs=6e-4)


def test_a_thin_strip_tends_to_one_third_and_orientation_does_not_matter():
    assert _beta(1000.0) == pytest.approx((1 - 0.630 / 1000) / 3, rel=1e-4)  # 1/3 (1 - 0.630 c / b)
    assert saint_venant_torsion_hz(SHEAR, RHO, 0.01, 0.02, 0.03) == saint_venant_torsion_hz(SHEAR, RHO, 0.02, 0.01,
                                                                                           0.03)


def test_the_rod_is_a_quarter_wave():
    assert rod_axial_hz(70e9, 2800.0, 0.03) == pytest.approx(math.sqrt(70e9 / 2800.0) / 0.12, rel=1e-15)


@pytest.mark.parametrize(("call", "named"), [
    (lambda: rod_axial_hz(70e9, 0.0, 0.03), "density"),
    (lambda: saint_venant_torsion_hz(SHEAR, RHO, 0.01, -0.01, 0.03), "height"),
])
def test_bad_inputs_are_refused(call, named):
    with pytest.raises(ValueError, match=named):
        call()


def test_the_studies_targets_are_the_closed_forms_at_the_default_bar():
    torsion = saint_venant_torsion_hz(SHEAR, RHO, 0.01, 0.01, 0.03)
    axial = rod_axial_hz(DURALUMIN.youngs_modulus, RHO, 0.03)
    assert (torsion, axial) == (pytest.approx(23462.848, abs=1e-3), pytest.approx(41666.667, abs=1e-3))
    resolved = {c.id: c.targets for c in load_study("elasticity").claims}
    for claim, value in (("continuum-torsion-saint-venant", torsion), ("continuum-axial-rod-theory", axial)):
        assert resolved[claim] and all(v == pytest.approx(value, rel=1e-12) for _, _, v in resolved[claim])
    typed = {c["id"]: c["target"] for c in tomllib.loads((STUDIES / "calibration.toml").read_text())["claim"]}
    assert typed["mca-modes-reference-torsion"] == pytest.approx(torsion, abs=0.01)
    assert typed["mca-modes-reference-axial"] == pytest.approx(axial, abs=0.01)
