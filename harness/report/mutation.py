"""How strong a study's claims are: the outcome of `pcverify mutate` as files and as a section of the study's
page.

`mutants.json` holds per mutant its file, what it breaks, its status (killed, survived, invalid, crashed) and
why, the claims that caught it, each claim's state on the baseline and on the mutant, its wall time and the
cells it recomputed; per claim the mutants it kills.  `mutants-matrix.csv` is the kill matrix (claims x
mutants).  A claim that passes and kills no mutant is *descriptive*: it reports a number, but no catalogued
defect of the code makes it fail (a claim that does not pass on the original is a finding: it can catch none).
"""

from __future__ import annotations

import html
import json
from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness.report.findings import by_claim, claim_state
from pcverify.harness.report.page import anchor, table_details
from pcverify.harness.run.files import atomic_write, read_json
from pcverify.harness.run.mutation import measured_catches

OUTCOMES = ("killed", "survived", "invalid", "crashed")
MUTANTS_FILE = "mutants.json"
MATRIX = "mutants-matrix"

e = html.escape


def mutation_document(study: str, baseline: list[dict[str, Any]], outcomes: list[dict[str, Any]],
                      wall_s: float) -> dict[str, Any]:
    """mutants.json: the study, the outcome per mutant, per claim its baseline state and the mutants it kills."""
    grouped = by_claim(baseline)
    claims = {claim: {"baseline": claim_state(rows), "passing": sum(r["verdict"] == "pass" for r in rows),
                      "kills": [o["name"] for o in outcomes if claim in o.get("caught_by", [])]}
              for (_, claim), rows in grouped.items()}
    for c in claims.values():  # a claim with no passing case is a finding: it can catch nothing
        c["descriptive"] = c["passing"] > 0 and not c["kills"]
    return {"study": study, "counts": {s: sum(o["status"] == s for o in outcomes) for s in OUTCOMES},
            "mutants": outcomes, "claims": claims, "wall_s": round(wall_s, 3)}


def kill_matrix(doc: dict[str, Any]) -> pd.DataFrame:
    """Claims x mutants: "killed (fail)" where the claim caught the mutant (its state on the mutant; "killed (fail,
    incidental)" where none of its caught cases measured a value), "pass" where
    it passed on both, "baseline fail" where it did not pass on the original, the mutant's status where it was
    not judged (invalid, crashed)."""
    rows = []
    for claim, c in doc["claims"].items():
        row: dict[str, Any] = {"claim": claim, "baseline": c["baseline"], "kills": len(c["kills"])}
        for o in doc["mutants"]:
            s = o.get("claims", {}).get(claim)
            if o["status"] in ("invalid", "crashed"):
                row[o["name"]] = o["status"]
            elif claim in o.get("caught_by", []):
                row[o["name"]] = f"killed ({s['mutant']}{'' if measured_catches(s) else ', incidental'})"
            elif s is None or not c.get("passing"):
                row[o["name"]] = f"baseline {c['baseline']}"
            else:
                row[o["name"]] = "pass"
        rows.append(row)
    return pd.DataFrame(rows, columns=["claim", "baseline", "kills", *(o["name"] for o in doc["mutants"])])


def write_mutation_report(out: Path, study: str, doc: dict[str, Any]) -> Path:
    """Write mutants.json and the kill matrix into the study's report folder and name them in its manifest (the
    study's page then shows the section); the manifest is left alone if it is not there."""
    folder = out / study
    folder.mkdir(parents=True, exist_ok=True)
    atomic_write(folder / MUTANTS_FILE, json.dumps(doc, indent=1))
    matrix = kill_matrix(doc)
    atomic_write(folder / f"{MATRIX}.csv", matrix.to_csv(index=False))
    manifest, why = read_json(folder / "manifest.json")
    if not why and isinstance(manifest, dict):
        manifest["mutants"] = MUTANTS_FILE
        atomic_write(folder / "manifest.json", json.dumps(manifest, indent=1))
    return folder / MUTANTS_FILE


def _names(names: list[str]) -> str:
    return ", ".join(f"<code>{e(n)}</code>" for n in names)


def mutation_section(folder: Path, name: str, doc: Any) -> str:
    """The study page's section on its mutants: per claim the mutants it kills (or "descriptive"), per mutant
    the claims that caught it, survivors, invalid and crashed ones with their reasons."""
    if not isinstance(doc, dict) or not isinstance(doc.get("mutants"), list) or not isinstance(doc.get("claims"),
                                                                                               dict):
        return ""
    counts = doc.get("counts", {})
    parts = [f"<h3 id='{anchor(name, 'mutants')}'>How strong are the claims? {len(doc['mutants'])} mutants: "
             + ", ".join(f"{counts.get(s, 0)} {s}" for s in OUTCOMES) + "</h3>",
             "<p class='meta'>A mutant is a deliberate defect of the code (<code>pcverify mutate</code>); a claim "
             "that passes on the original and not on the mutant has caught it. A claim that catches none is "
             f"<b>descriptive</b>. <a href='{e(name)}/{MUTANTS_FILE}'>{MUTANTS_FILE}</a> · "
             f"<a href='{e(name)}/{MATRIX}.csv'>kill matrix (CSV)</a></p>",
             "<table class='data' id='" + anchor(name, "mutants-claims") + "'><tr><th>claim</th><th>on the original"
             "</th><th>kills</th></tr>"]
    for claim, c in doc["claims"].items():
        kills = (_names(c.get("kills", [])) if c.get("kills") else
                 "<i>descriptive: kills no catalogued mutant</i>" if c.get("descriptive") else
                 "<i>does not pass on the original: it can catch no defect</i>")
        parts.append(f"<tr><td>{e(claim)}</td><td class='{e(str(c.get('baseline')))}'>{e(str(c.get('baseline')))}"
                     f"</td><td>{kills}</td></tr>")
    parts.append("</table><div class='scroll'><table class='data' id='" + anchor(name, "mutants-outcomes") +
                 "'><tr><th>mutant</th>"
                 "<th>status</th><th>caught by</th><th>breaks</th><th>file</th><th>expected</th><th>wall</th>"
                 "<th>cells recomputed</th><th>why</th></tr>")
    for o in doc["mutants"]:
        status = str(o.get("status")) + (f" ({o['kill']})" if o.get("kill") else "")
        css = {"killed": "pass", "survived": "fail", "invalid": "inconclusive", "crashed": "inconclusive"}.get(
            str(o.get("status")))
        css = "inconclusive" if o.get("kill") == "incidental" else css
        parts.append(f"<tr><td>{e(str(o.get('name')))}</td><td class='{css}'>{e(status)}</td>"
                     f"<td>{_names(o.get('caught_by') or []) or '—'}</td><td title='{e(str(o.get('breaks')))}'>"
                     f"{e(str(o.get('breaks')))}</td><td>{e(str(o.get('package')))}/{e(str(o.get('file')))}</td>"
                     f"<td>{_names(o.get('expect') or [])}</td><td>{float(o.get('wall_s') or 0):.1f} s</td>"
                     f"<td>{int(o.get('recomputed') or 0)}</td><td title='{e(str(o.get('reason') or ''))}'>"
                     f"{e(str(o.get('reason') or ''))}</td></tr>")
    parts.append("</table></div>")
    missed = [o for o in doc["mutants"] if o.get("status") != "killed" or o.get("kill") == "incidental"]
    if missed:
        parts.append("<p class='meta'>Not killed by a claim that measures them:</p><ul>" + "".join(
            f"<li><b>{e('killed incidentally' if o.get('kill') == 'incidental' else str(o.get('status')))}</b> "
            f"{e(str(o.get('name')))} ({e(str(o.get('package')))}/"
            f"{e(str(o.get('file')))}: {e(str(o.get('breaks')))}): {e(str(o.get('reason') or ''))}</li>"
            for o in missed) + "</ul>")
    if (folder / f"{MATRIX}.csv").is_file():
        try:
            parts.append(table_details(pd.read_csv(folder / f"{MATRIX}.csv"), f"{name}/{MATRIX}.csv",
                                       anchor(name, MATRIX)))
        except (OSError, ValueError):
            pass
    return "".join(parts)
