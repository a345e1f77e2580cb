"""The comparison of a cell's solution with its scene's reference (`catalogue.reference_of`: the scene spec's),
once, right after the solve; stored with the cell, so tables, calibrations and `pcverify run` read these numbers.

`errors`: per sample set, the absolute L2 (RMS) and L-infinity errors against the reference field (of a scalar
per point, or of a displacement by the length of its difference), in the solution's quantity, with the
reference's kind.  `scalar_errors`: per scalar the reference expects, the summary's
value under that name (NAME_given_CONDITION: the expected NAME given what the reference read from the summary),
the expected value and the relative error.  `fingerprint`: what the cell key holds of both.
"""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np

from pcverify.fingerprint import module_fingerprint
from pcverify.harness.judge.metrics import field_errors
from pcverify.harness.study.catalogue import reference_of, spec_modules
from pcverify.references.shared import number
from pcverify.scene import Scene


def errors(scene: Scene, samples: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    """{set: {"l2": ..., "linf": ..., "reference": kind}} for each non-empty sample set the scene has a
    reference for; a non-finite error (values of a run that is not ok) is None, as in the JSON of a result."""
    ref = reference_of(scene.name)
    if ref is None or ref.field is None:
        return {}
    out: dict[str, dict[str, Any]] = {}
    for name, entry in (samples or {}).items():
        values = np.asarray(entry["values"], dtype=float)
        if values.size == 0 or values.ndim > 2:
            continue
        exact = ref.field(scene, np.asarray(entry["points"], dtype=float))
        if exact is None or np.shape(exact) != values.shape:
            continue
        found = field_errors(values, exact)
        out[name] = {k: v if math.isfinite(v) else None for k, v in found.items()} | {"reference": ref.kind}
    return out


def scalar_errors(scene: Scene, summary: dict[str, Any] | None) -> dict[str, dict[str, Any]]:
    """{quantity: {"value", "expected", "error", "reference"}} for each scalar of the scene's reference: the
    summary's value under the same name and the relative error |value / expected - 1| (None where the solution
    does not report it as a finite number, where the expected value is not finite, or is 0: no relative error)."""
    ref = reference_of(scene.name)
    if ref is None or ref.scalars is None:
        return {}
    summary = summary or {}
    out: dict[str, dict[str, Any]] = {}
    for name, exact in ref.scalars(scene, summary).items():
        value = number(summary.get(name.partition("_given_")[0]))
        err = abs(value / exact - 1.0) if value is not None and exact != 0 else math.nan
        out[name] = {"value": value, "expected": float(exact) if math.isfinite(exact) else None,
                     "error": err if math.isfinite(err) else None, "reference": ref.kind}
    return out


def fingerprint(scene: Scene) -> str:
    """What the cell key holds of the compare step: this module's fingerprint (its imports' too) and those of the
    modules that define the scene's spec and reference (a plugin's scene included)."""
    parts = [module_fingerprint(__name__), *(module_fingerprint(m) for m in spec_modules(scene.name))]
    return hashlib.sha256(" ".join(parts).encode()).hexdigest()[:16]
