"""Which claim sees which input: the outcome of `pcverify sensitivity` as files and as a section of the study's
page.

`sensitivity.json` holds per input the cells that have it, the factor it was scaled by, how many cells' results
changed and, per claim case, the value before and after, the change, the scale it was held against, whether it
moved and whether its verdict changed; then the blind spots (inputs no claim sees: *inert* where no cell's
result changed, *unseen* where results changed and no claim moved, *unread* where only cells of groups no claim
reads have it), the claims no perturbed input moves and the inputs that could not be perturbed.
`sensitivity-matrix.csv` is the matrix inputs x claims.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness.report.page import anchor, table_details
from pcverify.harness.run.files import atomic_write, read_json

SENSITIVITY_FILE = "sensitivity.json"
MATRIX = "sensitivity-matrix"

e = html.escape


def mark(changes: list[dict[str, Any]]) -> str:
    """A claim's mark for one input: "verdict" (a case's verdict changed), "moved" (a case's value moved
    beyond its scale) or "" (unseen)."""
    flipped = [c for c in changes if c["verdict_changed"]]
    if flipped:
        return f"verdict {flipped[0]['verdict_before']}→{flipped[0]['verdict_after']}"
    return "moved" if any(c["moved"] for c in changes) else ""


def _in(entry: dict[str, Any]) -> str:
    """": PART CHANGE, ..." for the parts of the results that moved most (older documents do not say)."""
    parts = [f"{name} {change:.1e}" if isinstance(change, float) else f"{name} {change}"
             for name, change in (entry.get("moved_parts") or {}).items()]
    return f": {', '.join(parts)}" if parts else ""


def sensitivity_document(study: str, step: float, claims: list[str], entries: list[dict[str, Any]],
                         wall_s: float, not_reached: list[str] | None = None) -> dict[str, Any]:
    """sensitivity.json: per input its entry with the claims that see it, the blind spots, the inputs not
    perturbed (zero, out of range both ways, or refused by a solver's checks), and the claims no perturbation
    reaches (`not_reached`: they read a calibration's tables, whose runs the calibration makes)."""
    for entry in entries:
        entry["seen_by"] = [c for c, changes in entry.get("claims", {}).items() if mark(changes)]
    perturbed = [x for x in entries if x["status"] == "perturbed"]
    blind = [{"input": x["input"], "kind": "unseen" if x["changed_cells"] else "inert",
              "why": f"inert: no cell's result moved beyond round-off (largest relative change "
              f"{x['largest_change']:.1e})" if not x["changed_cells"] else f"unseen: {x['changed_cells']} of "
              f"{x['cells']} cells' results moved (up to {x['largest_change'] or math.inf:.1e} relative"
              f"{_in(x)}), no claim did"} for x in perturbed if not x["seen_by"]]
    blind += [{"input": x["input"], "kind": "unread", "why": f"unread: {x['reason']}"} for x in entries
              if x["status"] == "unread"]
    seeing = {c for x in perturbed for c in x["seen_by"]}
    return {"study": study, "step": step, "claims": claims, "inputs": entries, "blind_spots": blind,
            "claims_seeing_nothing": [c for c in claims if c not in seeing],
            "claims_not_reached": list(not_reached or []),
            "not_perturbed": [{"input": x["input"], "reason": x["reason"]} for x in entries
                              if x["status"] in ("not perturbed", "refused")],
            "counts": {"inputs": len(entries), "perturbed": len(perturbed),
                       "seen": sum(bool(x["seen_by"]) for x in perturbed), "blind": len(blind)},
            "wall_s": round(wall_s, 3)}


def matrix(doc: dict[str, Any]) -> pd.DataFrame:
    """Inputs x claims: each claim's mark (`mark`), with the input's cells, changed cells and seeing claims."""
    rows = [{"input": x["input"], "cells": x["cells"], "changed": x["changed_cells"], "seen_by": len(x["seen_by"])}
            | {c: mark(x["claims"].get(c, [])) for c in doc["claims"]}
            for x in doc["inputs"] if x["status"] == "perturbed"]
    return pd.DataFrame(rows, columns=["input", "cells", "changed", "seen_by", *doc["claims"]])


def write_sensitivity_report(out: Path, study: str, doc: dict[str, Any]) -> Path:
    """Write sensitivity.json and the matrix into the study's report folder and name them in its manifest (the
    study's page then shows the section)."""
    folder = out / study
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(folder / SENSITIVITY_FILE, json.dumps(doc, indent=1))
    atomic_write(folder / f"{MATRIX}.csv", matrix(doc).to_csv(index=False))
    manifest, why = read_json(folder / "manifest.json")
    if not why and isinstance(manifest, dict):
        manifest["sensitivity"] = SENSITIVITY_FILE
        atomic_write(folder / "manifest.json", json.dumps(manifest, indent=1))
    return folder / SENSITIVITY_FILE


def sensitivity_section(folder: Path, name: str, doc: Any) -> str:
    """The study page's section: counts, the blind spots, the inputs not perturbed, the matrix."""
    if not isinstance(doc, dict) or not isinstance(doc.get("inputs"), list) or not isinstance(doc.get("counts"), dict):
        return ""
    n = doc["counts"]
    parts = [f"<h3 id='{anchor(name, 'sensitivity')}'>Which claim sees which input? {n.get('perturbed')} inputs "
             f"scaled by 1 + {doc.get('step')}: {n.get('seen')} seen, {n.get('blind')} blind spots</h3>",
             "<p class='meta'>Each input the study's solvers are handed (a scene's numbers, a solver's number "
             "parameters), scaled in the solver only (<code>pcverify sensitivity</code>); a claim sees it when a "
             "case's value moves beyond its uncertainty, round-off and a thousandth of its tolerance. "
             f"<a href='{e(name)}/{SENSITIVITY_FILE}'>{SENSITIVITY_FILE}</a> · "
             f"<a href='{e(name)}/{MATRIX}.csv'>matrix (CSV)</a></p>"]
    if doc.get("blind_spots"):
        parts.append("<p class='meta'>Blind spots: inputs no claim sees</p><ul>" + "".join(
            f"<li><code>{e(str(b.get('input')))}</code>: {e(str(b.get('why')))}</li>" for b in doc["blind_spots"])
                     + "</ul>")
    if doc.get("claims_seeing_nothing"):
        parts.append("<p class='meta'>Claims no perturbed input moves: " + ", ".join(
            f"<code>{e(str(c))}</code>" for c in doc["claims_seeing_nothing"]) + "</p>")
    if doc.get("claims_not_reached"):
        parts.append("<p class='meta'>Claims no perturbation reaches (they read a calibration's runs): " + ", ".join(
            f"<code>{e(str(c))}</code>" for c in doc["claims_not_reached"]) + "</p>")
    if doc.get("not_perturbed"):
        parts.append("<details><summary>Inputs not perturbed</summary><ul>" + "".join(
            f"<li><code>{e(str(b.get('input')))}</code>: {e(str(b.get('reason')))}</li>" for b in doc["not_perturbed"])
                     + "</ul></details>")
    if (folder / f"{MATRIX}.csv").is_file():
        try:
            parts.append(table_details(pd.read_csv(folder / f"{MATRIX}.csv", keep_default_na=False),
                                       f"{name}/{MATRIX}.csv", anchor(name, MATRIX)))
        except (OSError, ValueError):
            pass
    return "".join(parts)
