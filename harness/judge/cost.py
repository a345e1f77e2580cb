"""Cost at a given error: the CPU seconds a solver needs to reach an error, read off its work-precision rows.

A cost claim (`at_error`) asks what a researcher asks: "how many CPU seconds to reach error e", or with `against`
"at most k times FiPy's cost at equal error".  The levels of a case are sorted by error and the cost is
interpolated linearly in log cost against log error between the two levels that bracket e; its uncertainty is
the spread of the timed repeats (`<metric>_unc`), interpolated alike.  Nothing is extrapolated: a case whose
levels do not reach e, or do not go above it, has no cost there and says which errors it spans.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd


def error_column(table: pd.DataFrame, named: str) -> tuple[str, str]:
    """(column, why not): the error column a cost claim reads, `named` or else the table's only `err.*` column."""
    if named:
        return (named, "") if named in table.columns else ("", f"error column {named} is not in the table")
    found = [c for c in table.columns if str(c).startswith("err.") and not str(c).endswith("_unc")]
    if len(found) == 1:
        return found[0], ""
    return "", f"error_metric must name one of its error columns ({', '.join(found) or 'it has none'})"


def cost_at(rows: pd.DataFrame, metric: str, error: str, at: float) -> tuple[float, float, str]:
    """(cost, its uncertainty, why not): `metric` at error `at`, log-log interpolated between the rows that
    bracket it (NaN uncertainty where the bracketing rows have no `<metric>_unc`)."""
    e = pd.to_numeric(rows[error], errors="coerce").to_numpy(float)
    c = pd.to_numeric(rows[metric], errors="coerce").to_numpy(float)
    u = (pd.to_numeric(rows[f"{metric}_unc"], errors="coerce").to_numpy(float) if f"{metric}_unc" in rows
         else np.full(len(rows), math.nan))
    ok = np.isfinite(e) & np.isfinite(c) & (e > 0) & (c > 0)
    if ok.sum() < len(rows) or len(rows) == 0:
        return math.nan, math.nan, f"a level has no positive finite {error} and {metric}"
    order = np.argsort(e)
    e, c, u = e[order], c[order], u[order]
    if not e[0] <= at <= e[-1]:
        return math.nan, math.nan, (f"its levels reach {error} from {e[0]:.3g} to {e[-1]:.3g}, not {at:.3g} "
                                    "(a cost is interpolated, never extrapolated)")
    hi = int(np.searchsorted(e, at))
    if e[hi] == at:
        return float(c[hi]), float(u[hi]), ""
    lo = hi - 1
    w = (math.log(at) - math.log(e[lo])) / (math.log(e[hi]) - math.log(e[lo]))
    cost = math.exp((1 - w) * math.log(c[lo]) + w * math.log(c[hi]))
    return cost, float((1 - w) * u[lo] + w * u[hi]), ""
