"""Checks of what a report figure draws, read from the description the report saves beside it (NAME.json).

A figure passes when every legend entry names a series (on any of its axes) with at least one visible
point, no two labelled series on one axes draw the same points, and no legend covers a drawn data point.
Used by the report tests; also a script over a report folder:

    python tests/figure_checks.py reports/
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from pcverify.harness.report.figures import same_series


def problems(description: dict[str, Any]) -> list[str]:
    """What is wrong with one figure's description (empty when nothing is)."""
    axes = description["axes"]
    visible: dict[str, int] = {}
    for ax in axes:
        for s in ax["series"]:
            visible[s["label"]] = max(visible.get(s["label"], 0), s["visible_points"])
    found = []
    for k, ax in enumerate(axes):
        where = f"axes {k + 1} ({ax['title'] or ax['ylabel']})"
        for label in ax["legend"]:
            if visible.get(label, 0) < 1:
                found.append(f"{where}: legend entry {label!r} has no visible point drawn")
        labelled = [s for s in ax["series"] if not s["label"].startswith("_")]
        for i, a in enumerate(labelled):
            for b in labelled[i + 1:]:
                if same_series(_values(a["x"]), _values(a["y"]), _values(b["x"]), _values(b["y"])):
                    found.append(f"{where}: series {b['label']!r} duplicates {a['label']!r}")
        if ax["legend_covers"]:
            found.append(f"{where}: the legend covers {ax['legend_covers']} drawn data points")
    return found


def _values(values: list[float | None]) -> list[float]:
    return [float("nan") if v is None else v for v in values]


def report_problems(out: Path) -> dict[str, list[str]]:
    """Problems of every figure listed in the manifests under a report folder, by figure path."""
    found = {}
    for manifest in sorted(out.glob("*/manifest.json")):
        for section in json.loads(manifest.read_text())["sections"]:
            for fig in section["figures"]:
                desc = (manifest.parent / fig).with_suffix(".json")
                key = str(desc.relative_to(out).with_suffix(".png"))
                if not desc.exists():
                    found[key] = ["no description (NAME.json) beside the figure"]
                    continue
                found[key] = problems(json.loads(desc.read_text()))
    return found


if __name__ == "__main__":
    report = report_problems(Path(sys.argv[1] if len(sys.argv) > 1 else "reports"))
    bad = {k: v for k, v in report.items() if v}
    for fig, found in bad.items():
        print(fig)
        for p in found:
            print(f"  {p}")
    print(f"{len(report)} figures checked, {len(bad)} with problems")
    sys.exit(1 if bad else 0)
