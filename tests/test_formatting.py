"""Numbers for people: units, engineering prefixes, digits matched to the uncertainty."""

import math

import pytest

from pcverify.harness.report.formatting import GROUP, cell, digits_for, measured, number, unit_of


@pytest.mark.parametrize("value, unit, digits, text", [
    (7e10, "Pa", 3, "70.0 GPa"),
    (3.98e8, "Pa", 3, "398 MPa"),
    (8412.7, "Hz", 5, f"8{GROUP}412.7 Hz"),
    (1.47059e-07, "", 3, "1.47 × 10⁻⁷"),
    (0.0012, "s", 3, "1.20 ms"),
    (0.005, "m", 2, "5.0 mm"),
    (0.31759, "", 4, "0.3176"),
    (-2.5e-4, "", 2, "−2.5 × 10⁻⁴"),
    (999.96, "", 4, f"1{GROUP}000"),  # rounding carries into the next decade
    (123456.0, "", 3, "1.23 × 10⁵"),
    (0.0, "Pa", 3, "0 Pa"),
    (math.nan, "Pa", 3, "—"),
    (math.inf, "", 3, "∞"),
])
def test_number(value, unit, digits, text):
    assert number(value, unit, digits) == text


def test_digits_follow_the_uncertainty_then_the_tolerance():
    assert digits_for(0.31234, uncertainty=0.0012) == 4  # 0.3123 ± 0.0012
    assert digits_for(7e10, tolerance=1.4e9) == 3  # 70.0 GPa judged within 1.4 GPa
    assert digits_for(2.3e-15, tolerance=1e-9) == 2  # far below the tolerance: two digits say so
    assert digits_for(0.1, uncertainty=1.8) == 1
    assert measured(0.31234, "", 0.0012) == "0.3123 ± 0.0012"
    assert measured(6.99999e10, "Pa", tolerance=1.4e9) == "70.0 GPa"
    assert measured(10.0, "", tolerance=0) == "10"  # a count judged exactly (cells not matched)
    assert measured(12345.0, "", tolerance=0) == f"12{GROUP}345"
    assert measured(0.5, "", tolerance=0) == "0.5000"  # not a whole number: default digits


def test_units_of_result_columns():
    assert unit_of("E_eff") == "Pa" and unit_of("f3_hz") == "Hz" and unit_of("err.f3_hz") == ""
    assert unit_of("wall_s") == "s" and unit_of("work.solve_s") == "s" and unit_of("bulk_median") == ""
    assert unit_of("extrapolated", quantity="f1_hz") == "Hz"


def test_table_cells():
    assert cell(4, "n") == "4" and cell(12345, "unknowns") == f"12{GROUP}345"
    assert cell(7e10, "E_eff") == "70.00 GPa" and cell("fipy", "solver") == "fipy" and cell(None, "x") == ""
