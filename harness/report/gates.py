"""The exit codes of `study --strict` and `mutate --strict`: a CI gate that fails unless everything passed,
listing on stderr each verdict that is not a pass, or each mutant that was not killed, with why."""

from __future__ import annotations

import sys
from typing import Any

GATE_STATES = ("fail", "inconclusive", "not-applicable")  # what --strict refuses: anything not verified


def verdict_gate(records: list[dict[str, Any]], strict: bool) -> int:
    """Exit code of `study`: with --strict, 1 when any verdict is not a pass (fail, inconclusive or not
    applicable), each listed on stderr with why and the command that reproduces it."""
    bad = [r for r in records if r.get("verdict") in GATE_STATES]
    if not strict or not bad:
        return 0
    for r in bad:
        case = f" {r['case']}" if r.get("case") else ""
        value = "no value" if r.get("value") is None else f"{r['metric']} = {r['value']!r}"
        unc = f" ± {r['uncertainty']!r}" if r.get("uncertainty") is not None else ""
        target = "" if r.get("target") is None else f", target {r['target']!r}"
        why = f"; why: {r['note']}" if r.get("note") else ""
        print(f"pcverify: claim {r['verdict']}: {r['study']}/{r['claim']}{case}: {value}{unc}{target} ({r['sense']}, "
              f"tolerance {r['tolerance']!r}, {r['reference']}){why}; reproduce: {r['command']}", file=sys.stderr)
    counts = ", ".join(f"{sum(r['verdict'] == s for r in bad)} {s}" for s in GATE_STATES)
    print(f"pcverify: {len(bad)} of {len(records)} verdicts are not a pass ({counts}) (--strict)", file=sys.stderr)
    return 1


def mutant_gate(docs: list[dict[str, Any]], strict: bool) -> int:
    """Exit code of `mutate`: with --strict, 1 when a mutant run is not killed (survived, invalid or crashed) or
    killed only where no claim measured it (`kill` incidental), each listed on stderr with why."""
    bad = [(d["study"], o) for d in docs for o in d["mutants"]
           if o["status"] != "killed" or o.get("kill") == "incidental"]
    if not strict or not bad:
        return 0
    for study, o in bad:
        state = "killed incidentally" if o["status"] == "killed" else o["status"]
        print(f"pcverify: mutant {state}: {study}/{o['name']} ({o['package']}/{o['file']}: {o['breaks']}): "
              f"{o['reason']}", file=sys.stderr)
    total = sum(len(d["mutants"]) for d in docs)
    counts = ", ".join(f"{sum(o['status'] == s for _, o in bad)} {s}" for s in ("survived", "invalid", "crashed"))
    counts += f", {sum(o['status'] == 'killed' for _, o in bad)} killed incidentally"
    print(f"pcverify: {len(bad)} of {total} mutants are not killed by a claim that measures them ({counts}) "
          "(--strict)", file=sys.stderr)
    return 1
