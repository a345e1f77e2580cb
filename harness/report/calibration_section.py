"""The report section of a calibration: its title (what it was calibrated and validated on), its figures (the
objective against evaluation and against cost, the validation errors) and its tables."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness.report import figures
from pcverify.harness.run.calibration import Outcome


def calibration_section(outcome: Outcome, folder: Path) -> tuple[dict[str, Any], dict[str, pd.DataFrame]]:
    """The report section of a calibration (title, figures drawn into `folder`) and its tables."""
    cal, t = outcome.calibration, outcome.tables
    folder.mkdir(parents=True, exist_ok=True)
    figs = []
    trace = t[f"{cal.id}-trace"]
    if figures.calibration_trace(trace, folder / f"{cal.id}-trace", f"{cal.title}: objective against evaluation"):
        figs.append(f"{cal.id}-trace.png")
    if figures.calibration_work_precision(trace, folder / f"{cal.id}-work-precision",
                                          f"{cal.title}: objective against cost of each evaluated set"):
        figs.append(f"{cal.id}-work-precision.png")
    if figures.calibration_validation(t[f"{cal.id}-validation"], cal.tolerance, folder / f"{cal.id}-validation",
                                      f"{cal.title}: error per cell, calibrated and default parameters"):
        figs.append(f"{cal.id}-validation.png")
    title = (f"Calibration {cal.id} ({cal.solver}): {cal.title}. Calibrated on: "
             f"{'; '.join(c.describe() for c in cal.calibrate)}. Validated on: "
             f"{'; '.join(c.describe() for c in cal.validate)}")
    return {"id": cal.id, "title": title, "figures": figs}, t
