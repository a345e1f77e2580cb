"""Numbers for people: the unit of each table column, engineering prefixes, significant digits.

Scene and solver parameters carry their units in their Param specs; the columns of result tables (summary
scalars, errors, fits) do not, so their units live here, in one place.  `number` turns a value into text
such as "70.0 GPa", "8 412.7 Hz" or "1.47 × 10⁻⁷", with as many significant digits as its uncertainty
supports (or as its tolerance needs to be judged, when it has no uncertainty).
"""

from __future__ import annotations

import math
import re
from typing import Any

# Units of result columns by exact name; patterns below cover families (f1_hz, work.solve_s, err.*).
COLUMN_UNITS: dict[str, str] = {
    "E_eff": "Pa", "failure_stress": "Pa", "strength_expected": "Pa", "reaction_force": "N",
    "mean_kinetic_energy": "J", "omega_max": "rad/s", "h": "m", "dt": "s", "dt_limit": "s",
    "dt_limit_single_mode": "s", "dt_theory": "s", "unknowns": "", "particles": "",
}
COLUMN_PATTERNS: tuple[tuple[str, str], ...] = (
    (r"^err\.", ""),  # relative errors
    (r"_hz$", "Hz"),
    (r"(^|[._])(wall|kernel|kernel_cpu|ramp|assembly|solve|postprocess)_s$", "s"),
)
# prefixes are used from this magnitude on (and below 1); Hz reads best unprefixed ("8 412.7 Hz")
PREFIX_FROM = {"Pa": 1e4, "N": 1e4, "J": 1e4, "m": 1e4, "s": 1e4, "Hz": 1e5, "W": 1e4}
PREFIXES = {-12: "p", -9: "n", -6: "µ", -3: "m", 0: "", 3: "k", 6: "M", 9: "G", 12: "T"}
SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")
GROUP = "\u202f"  # narrow no-break space between digit groups
DEFAULT_DIGITS = 4


def unit_of(column: str, quantity: str | None = None) -> str:
    """The unit of a result column ("" when dimensionless or unknown).  Columns of fits tables that hold
    the followed quantity's value (finest, extrapolated) take the unit of `quantity`."""
    if column in ("finest", "extrapolated") and quantity:
        return unit_of(quantity)
    if column in COLUMN_UNITS:
        return COLUMN_UNITS[column]
    for pattern, unit in COLUMN_PATTERNS:
        if re.search(pattern, column):
            return unit
    return ""


def digits_for(value: float, uncertainty: float = math.nan, tolerance: float = math.nan) -> int:
    """Significant digits of `value`: down to the second digit of its uncertainty; without one, down to a
    tenth of the tolerance it is judged against (2 to 6 digits); else DEFAULT_DIGITS."""
    if not math.isfinite(value) or value == 0:
        return DEFAULT_DIGITS
    lead = math.floor(math.log10(abs(value)))
    if math.isfinite(uncertainty) and uncertainty > 0:
        return max(1, min(12, lead - math.floor(math.log10(uncertainty)) + 2))
    if math.isfinite(tolerance) and tolerance > 0:
        return max(2, min(6, lead - math.floor(math.log10(tolerance / 10)) + 1))
    return DEFAULT_DIGITS


def _place_point(mantissa: str, point: int) -> str:
    """Digits `mantissa` (no point) with the decimal point after `point` digits (may be <= 0 or beyond)."""
    if point <= 0:
        return "0." + "0" * -point + mantissa
    if point >= len(mantissa):
        return mantissa + "0" * (point - len(mantissa))
    return mantissa[:point] + "." + mantissa[point:]


def _grouped(text: str) -> str:
    """Thousands grouped with a narrow no-break space in the integer part (4 digits and more)."""
    whole, dot, frac = text.partition(".")
    if len(whole) >= 4:
        whole = re.sub(r"(?<=\d)(?=(\d{3})+$)", GROUP, whole)
    return whole + dot + frac


def number(value: Any, unit: str = "", digits: int = DEFAULT_DIGITS) -> str:
    """`value` with `digits` significant digits and its unit: engineering prefixes for prefixable units
    (70.0 GPa, 398 MPa, 1.20 ms), plain decimals in [1e-3, 1e5) otherwise, and m × 10ⁿ beyond."""
    if value is None or isinstance(value, bool):
        return "" if value is None else str(value)
    try:
        v = float(value)
    except (TypeError, ValueError):
        return str(value)
    space = " " if unit else ""
    if math.isnan(v):
        return "—"
    if math.isinf(v):
        return ("−∞" if v < 0 else "∞") + space + unit
    if v == 0:
        return "0" + space + unit
    sign = "−" if v < 0 else ""
    mant, exp_text = f"{abs(v):.{max(digits, 1) - 1}e}".split("e")
    exp = int(exp_text)
    mant = mant.replace(".", "")
    if unit in PREFIX_FROM and (abs(v) >= PREFIX_FROM[unit] or abs(v) < 1):
        e3 = max(-12, min(12, 3 * math.floor(exp / 3)))
        return f"{sign}{_grouped(_place_point(mant, exp - e3 + 1))} {PREFIXES[e3]}{unit}"
    if -3 <= exp < 5:
        return f"{sign}{_grouped(_place_point(mant, exp + 1))}{space}{unit}"
    lead = _place_point(mant, 1).rstrip(".")
    return f"{sign}{lead} × 10{str(exp).translate(SUPERSCRIPT)}{space}{unit}"


def measured(value: Any, unit: str = "", uncertainty: Any = math.nan, tolerance: Any = math.nan) -> str:
    """A measured value with its unit, digits matched to its uncertainty (shown as ± u) or tolerance.
    A whole number judged with zero tolerance and no uncertainty is a count and is written exactly."""
    v, u, tol = (to_float(x) for x in (value, uncertainty, tolerance))
    if tol == 0 and not (math.isfinite(u) and u > 0) and math.isfinite(v) and v.is_integer() and abs(v) < 1e15:
        return _grouped(str(int(v))) + (f" {unit}" if unit else "")
    text = number(v, unit, digits_for(v, u, tol))
    if math.isfinite(u) and u > 0 and math.isfinite(v):
        text += f" ± {number(u, unit, 2)}"
    return text


def to_float(x: Any) -> float:
    """`x` as a float; NaN for None or anything that is not a number."""
    try:
        return math.nan if x is None else float(x)
    except (TypeError, ValueError):
        return math.nan


def cell(value: Any, column: str) -> str:
    """One table cell for people: a number with its column's unit, anything else as text."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        if isinstance(value, int) or (float(value).is_integer() and abs(value) < 1e6 and not unit_of(column)):
            return _grouped(str(int(value))) if math.isfinite(value) else number(value)
        return number(value, unit_of(column))
    return "" if value is None else str(value)
