"""The comparison of a cell's solution with its scene's reference: once, right after the solve.

Per sample set, the absolute L2 (root mean square) and L-infinity errors of the sampled values against the
reference at the same points (in the units of the solution's `quantity`), with the kind of reference they
stand on: "analytic" (the exact solution, `pcverify.references.analytic`).  The errors are stored with the
cell (its `errors`), so the tables, the calibrations and `pcverify run` read the numbers computed here from
the cell's own Scene, never from a scene rebuilt by name.  A scene without a reference has no errors, nor
has a set of vector values (a displacement): the reference is one scalar per point.  A scene whose reference
is a set of scalars (the stick-slip cycle, `pcverify.references.stick_slip.expected`) gets, per scalar the
solution's summary reports under the same name, its expected value and relative error (`scalar_errors`).  The
cell key holds this module's fingerprint (and that of the references it imports).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pcverify.harness.judge.metrics import field_errors
from pcverify.harness.spec.catalogue import get_spec
from pcverify.references import analytic, stick_slip
from pcverify.scene import Scene, SceneError


def errors(scene: Scene, samples: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    """{set: {"l2": ..., "linf": ..., "reference": kind}} for each non-empty sample set the scene has a
    reference for; a non-finite error (values of a run that is not ok) is None, as in the JSON of a result."""
    out: dict[str, dict[str, Any]] = {}
    field = _reference_field(scene)
    for name, entry in (samples or {}).items():
        values = np.asarray(entry["values"], dtype=float)
        if values.size == 0 or values.ndim != 1:
            continue
        exact = (field or analytic)(scene, np.asarray(entry["points"], dtype=float))
        if exact is None:
            continue
        found = field_errors(values, exact)
        out[name] = {k: v if math.isfinite(v) else None for k, v in found.items()} | {"reference": "analytic"}
    return out



def _reference_field(scene: Scene) -> Any:
    """The field of the scene's spec's reference (None: none, or a scene no catalogue entry names)."""
    try:
        reference = get_spec(scene.name).reference
    except SceneError:
        return None
    return reference.field if reference is not None else None


def scalar_errors(scene: Scene, summary: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    """{quantity: {"value", "expected", "error", "reference"}} for each scalar of the scene's analytic reference:
    the summary's value under the same name and the relative error |value / expected - 1| (None where the
    solution does not report it as a finite number).  For the stick-slip cycle also the kinetic half given the
    measured breakaway force (`stick_slip.given_peak`: NAME_given_peak, the value the summary's NAME; every
    entry None when the breakaway force is not reported or not above mu_k N), and an incline's acceleration
    (slide_acceleration; its error None where the block sticks: 0 has no relative error)."""
    summary = summary or {}
    expected = stick_slip.expected(scene)
    setting = stick_slip.setting(scene)
    if setting is not None:
        peak = _number(summary.get("spring_peak_N"))
        given = stick_slip.given_peak(setting, peak if peak is not None else math.nan)
        expected |= {f"{name}_given_peak": given.get(f"{name}_given_peak", math.nan)
                     for name in ("spring_trough_N", "spring_max_N", "stick_s", "slip_s", "period_s",
                                  "slip_velocity_peak")}
    incline = stick_slip.incline_acceleration(scene)
    if incline is not None:
        expected["slide_acceleration"] = incline
    out: dict[str, dict[str, Any]] = {}
    for name, exact in expected.items():
        value = _number(summary.get(name.removesuffix("_given_peak")))
        err = abs(value / exact - 1.0) if value is not None and exact != 0 else math.nan
        out[name] = {"value": value, "expected": float(exact) if math.isfinite(exact) else None,
                     "error": err if math.isfinite(err) else None, "reference": "analytic"}
    return out


def _number(value: Any) -> float | None:
    """A summary value as a finite float, else None."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None
