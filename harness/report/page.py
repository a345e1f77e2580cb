"""The HTML of the report page: summary, findings, verdicts by claim with a filter, study sections with
figures and collapsed tables, navigation.  Pure functions from data to HTML text; report.py writes the page.

The page is self-contained (figures embedded, a few lines of inline script for the filter, no network).
"""

from __future__ import annotations

import base64
import html
import math
from pathlib import Path
from typing import Any

import pandas as pd

from pcverify.harness.judge.verdict import LOOSE
from pcverify.harness.report.findings import (
    STATES,
    by_claim,
    claim_slack,
    claim_state,
    orders_text,
    solvers_of,
    state_counts,
    target_text,
    tolerance_text,
    value_text,
)
from pcverify.harness.report.formatting import cell, measured, number

MAX_TABLE_ROWS = 200  # rows shown in a collapsed table; the CSV beside it has all of them

CSS = """
*{box-sizing:border-box}
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:0;color:#1d1d1f;font-size:14px}
nav{position:fixed;top:0;left:0;bottom:0;width:230px;overflow-y:auto;background:#f4f5f7;border-right:1px solid #ddd;
 padding:10px 10px 40px;font-size:12px;line-height:1.45}
nav a{color:#124;text-decoration:none;display:block;overflow:hidden;text-overflow:ellipsis;white-space:nowrap}
nav a:hover{text-decoration:underline}nav .study{font-weight:600;margin-top:8px}nav .group{padding-left:10px}
nav .figure{padding-left:22px;color:#456}
main{margin-left:230px;padding:0 24px 40px;max-width:1180px}
h1{font-size:22px;margin:10px 0 2px}h2{font-size:18px;border-bottom:1px solid #999;margin-top:28px}
h3{font-size:15px;margin:18px 0 6px}
.meta{color:#555;font-size:12px;margin:0 0 8px}
table{border-collapse:collapse;font-size:12px}
td,th{border:1px solid #d4d4d4;padding:2px 6px;text-align:left;vertical-align:top}
th{background:#f0f0f0}
.pass{background:#d9f2d0}.fail{background:#f7cfcf}.inconclusive{background:#fbe7b5}.not-applicable{background:#e8e8e8}
.count{text-align:right;font-variant-numeric:tabular-nums;min-width:2.5em}
.count.fail:empty,.count.pass:empty,.count.inconclusive:empty{background:none}
#summary-table{width:100%;table-layout:fixed}
#summary-table td{white-space:nowrap;overflow:hidden;text-overflow:ellipsis}
#findings li{margin:3px 0}#findings ul{padding-left:18px}
.verdict-word{font-weight:600;padding:0 4px;border-radius:3px}
.filter{display:flex;gap:12px;align-items:center;margin:6px 0 8px;font-size:13px;flex-wrap:wrap}
#verdicts-table{width:100%}#verdicts-table td.claim{width:34%}
.statement{color:#333}.loose{color:#fff;background:#b35900;border-radius:3px;padding:0 3px}
.ref{font-size:11px;color:#555;border:1px solid #bbb;border-radius:3px;padding:0 3px}
.cases{display:flex;flex-wrap:wrap;gap:4px}
.case{border-radius:4px;padding:1px 5px;font-size:12px;border:1px solid rgba(0,0,0,.12)}
.case summary{cursor:pointer;white-space:nowrap}
.case dl{margin:4px 0;display:grid;grid-template-columns:auto auto;gap:0 8px;font-size:11px}
.case dd{margin:0}
code{font-size:11px;background:#f3f3f3;padding:1px 3px;border-radius:3px;word-break:break-all}
figure{margin:8px 0 14px}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:11px;color:#555}
details.table{margin:4px 0}details.table summary{cursor:pointer;font-size:12px}
.scroll{overflow-x:auto;max-width:100%}
table.data td{max-width:22em;overflow:hidden;text-overflow:ellipsis;white-space:nowrap;
 font-variant-numeric:tabular-nums}
"""

SCRIPT = """
(function(){
  const rows = Array.from(document.querySelectorAll('#verdicts-table tr.claim'));
  const pick = id => document.getElementById(id);
  const button = pick('hide-passing');
  function apply(){
    const study = pick('filter-study').value, solver = pick('filter-solver').value,
          verdict = pick('filter-verdict').value, hide = button.getAttribute('aria-pressed') === 'true';
    let shown = 0;
    for (const tr of rows){
      const ok = (!study || tr.dataset.study === study) &&
                 (!solver || tr.dataset.solvers.split(' ').includes(solver)) &&
                 (!verdict || tr.dataset.verdicts.split(' ').includes(verdict)) &&
                 !(hide && tr.dataset.state === 'pass');
      tr.hidden = !ok; shown += ok;
    }
    pick('filter-count').textContent = shown + ' of ' + rows.length + ' claims shown';
  }
  for (const id of ['filter-study','filter-solver','filter-verdict']) pick(id).addEventListener('change', apply);
  button.addEventListener('click', () => {
    button.setAttribute('aria-pressed', button.getAttribute('aria-pressed') === 'true' ? 'false' : 'true');
    button.textContent = button.getAttribute('aria-pressed') === 'true' ? 'show passing claims' : 'hide passing claims';
    apply();
  });
  apply();
})();
"""

e = html.escape


def anchor(*parts: str) -> str:
    """An id for the page from names (letters, digits, - and _ kept)."""
    return "-".join("".join(c if c.isalnum() or c in "-_" else "-" for c in p) for p in parts)


def figure_id(study: str, figure: str) -> str:
    return anchor("fig", study, Path(figure).stem)


def navigation(manifests: list[tuple[Path, dict[str, Any]]], has_benchmarks: bool) -> str:
    """The sidebar: summary, findings, verdicts, every study, group and figure, benchmarks, provenance."""
    parts = ["<nav id='nav' aria-label='contents'><b>pcverify report</b>",
             "<a href='#summary'>Summary</a><a href='#findings'>Findings</a><a href='#verdicts'>Verdicts by claim</a>"]
    for _, man in manifests:
        parts.append(f"<a class='study' href='#{anchor(man['name'])}' title='{e(man['title'])}'>{e(man['name'])}</a>")
        for sec in man["sections"]:
            parts.append(f"<a class='group' href='#{anchor(man['name'], sec['id'])}' title='{e(sec['title'])}'>"
                         f"{e(sec['id'])}</a>")
            parts += [f"<a class='figure' href='#{figure_id(man['name'], f)}'>▸ {e(Path(f).stem)}</a>"
                      for f in sec["figures"]]
        parts += [f"<a class='group' href='#{anchor(man['name'], key)}'>{key}</a>" for key in ("mutants", "sensitivity")
                  if man.get(key)]
    if has_benchmarks:
        parts.append("<a class='study' href='#benchmarks'>Benchmarks</a>")
    parts.append("<a class='study' href='#provenance'>Provenance</a></nav>")
    return "".join(parts)


def _count(n: int, state: str) -> str:
    return f"<td class='count {state if n else ''}'>{n or ''}</td>"


def summary_section(lines: list[dict[str, Any]], records: list[dict[str, Any]], meta: str) -> str:
    """The first screen: one line per study and solver (failures first) with counts, orders, headline."""
    total = state_counts(records)
    head = (f"<section id='summary'><h1>pcverify report</h1><p class='meta'>{e(meta)} · {len(records)} verdicts: "
            f"<span class='verdict-word fail'>{total['fail']} fail</span> "
            f"<span class='verdict-word inconclusive'>{total['inconclusive']} inconclusive</span> "
            f"<span class='verdict-word not-applicable'>{total['not-applicable']} not applicable</span> "
            f"<span class='verdict-word pass'>{total['pass']} pass</span> · "
            "<a href='verdicts.json'>verdicts.json</a></p>")
    rows = ["<table id='summary-table'><colgroup><col style='width:11%'><col style='width:11%'>"
            "<col style='width:4.5%'><col style='width:5.5%'><col style='width:4.5%'><col style='width:4.5%'>"
            "<col style='width:24%'><col></colgroup><tr><th>study</th><th>solver</th><th>fail</th>"
            "<th title='inconclusive: the uncertainty band straddles the bound'>incon&shy;clusive</th><th>n/a</th>"
            "<th>pass</th>"
            "<th>observed orders</th><th>headline (farthest from its bound)</th></tr>"]
    for line in lines:
        short, full = orders_text(line["orders"])
        h = line["headline"]
        headline = "no claim" if h is None else (
            f"<span class='verdict-word {h['verdict']}'>{e(h['verdict'])}</span> "
            f"{e(' '.join(filter(None, (h['claim'], h.get('case')))))}: {e(value_text(h))} vs {e(target_text(h))} "
            f"({e(tolerance_text(h))})"
            if h.get("value") is not None else f"{e(h['claim'])}: {e(h['verdict'])} ({e(str(h.get('note') or ''))})")
        title = "" if h is None else f"{h['statement']} ({h['reference']})"
        rows.append(f"<tr><td><a href='#{anchor(line['study'])}'>{e(line['study'])}</a></td>"
                    f"<td>{e(line['solver'])}</td>"
                    f"{_count(line['fail'], 'fail')}{_count(line['inconclusive'], 'inconclusive')}"
                    f"{_count(line['not-applicable'], 'not-applicable')}"
                    f"{_count(line['pass'], 'pass')}<td title='{e(full)}'>{e(short) or '—'}</td>"
                    f"<td title='{e(title)}'>{headline}</td></tr>")
    rows.append("</table>")
    return head + "".join(rows) + "</section>"


def findings_section(found: list[dict[str, Any]]) -> str:
    items = [f"<li><span class='verdict-word {f['state']}'>{e(f['state'])}</span> "
             f"<a href='#{anchor(f['study'])}'>{e(f['study'])}</a> · {e(f['text'])}</li>" for f in found]
    return ("<section id='findings'><h2>Findings</h2><p class='meta'>One sentence per claim, generated from its "
            "verdicts: failures first.</p><ul>" + "".join(items) + "</ul></section>")


def _case_chip(r: dict[str, Any]) -> str:
    label = r.get("case") or "all"
    shown = value_text(r) if r.get("value") is not None else ("n/a" if r["verdict"] == "not-applicable" else "no value")
    fields = [("verdict", r["verdict"]), ("solver", r.get("solver") or ""), ("value", value_text(r)),
              ("target", target_text(r)), ("error", measured(r.get("error"), "", math.nan, r.get("tolerance"))),
              ("uncertainty", number(r.get("uncertainty"), "", 2)), ("tolerance", number(r.get("tolerance"), "", 3)),
              ("reference", r["reference"]), ("note", r.get("note") or "")]
    fields.insert(-1, ("basis", r.get("basis") or ""))
    fields.insert(-3, ("tolerance/deviation", number(r.get("slack"), "", 3)))
    if r.get("value") is None:
        fields = [f for f in fields if f[0] in ("verdict", "solver", "reference", "note")]
    hover = "; ".join(f"{k}: {v}" for k, v in fields if v) + f"; command: {r.get('command') or ''}"
    body = "".join(f"<dt>{k}</dt><dd>{e(str(v))}</dd>" for k, v in fields if v)
    body += f"<dt>command</dt><dd><code>{e(r.get('command') or '')}</code></dd>"
    return (f"<details class='case {r['verdict']}' title='{e(hover)}'><summary>{e(label)}: {e(shown)}</summary>"
            f"<dl>{body}</dl></details>")


def _tolerance_line(rows: list[dict[str, Any]]) -> str:
    """The claim's tolerance against what it measured, and where the tolerance comes from (loose flagged)."""
    ratio, loose = claim_slack(rows)
    basis = str(rows[0].get("tolerance_basis") or "no basis given")
    if not math.isfinite(ratio):
        return f"<div class='tolerance meta'>tolerance basis: {e(basis)}</div>" if rows[0].get("tolerance_basis") \
            else ""
    flag = "<span class='loose' title='a tenfold worse value would pass, and the tolerance is not derived'>" \
           "loose</span> " if loose else ""
    return (f"<div class='tolerance meta'>{flag}tolerance {ratio:.3g}&times; the largest deviation measured; "
            f"{e(basis)}</div>")


def verdicts_section(records: list[dict[str, Any]]) -> str:
    """One row per claim (statement once), its cases as coloured cells; a filter by study, solver, verdict."""
    claims = by_claim(records)
    loose = sorted(f"{s}/{c}" for (s, c), rows in claims.items() if claim_slack(rows)[1])
    studies = sorted({r["study"] for r in records})
    solvers = sorted({s for r in records for s in solvers_of(r)})
    options = lambda vals: "".join(f"<option value='{e(v)}'>{e(v)}</option>" for v in vals)  # noqa: E731
    parts = ["<section id='verdicts'><h2>Verdicts by claim</h2><p class='meta'>Each claim once, its cases as cells "
             "(green pass, red fail, amber inconclusive: the uncertainty band straddles the bound, grey not "
             "applicable); hover or open a cell for value, target, error, uncertainty, "
             "tolerance and the command that reproduces the number. Under each statement: its tolerance over "
             "the largest deviation its cases measured, and the tolerance's basis (derived, or measured with a "
             f"factor); above {LOOSE:g}&times; and not derived, it is loose: a tenfold worse value would pass. "
             f"Loose: {e(', '.join(loose)) or 'none'}.</p>",
             "<div class='filter'><label>study <select id='filter-study'><option value=''>all</option>"
             f"{options(studies)}</select></label><label>solver <select id='filter-solver'><option value=''>all"
             f"</option>{options(solvers)}</select></label><label>verdict <select id='filter-verdict'>"
             f"<option value=''>any</option>{options(STATES)}</select></label>"
             "<button id='hide-passing' type='button' aria-pressed='false'>hide passing claims</button>"
             "<span id='filter-count' class='meta'></span></div>",
             "<table id='verdicts-table'><tr><th>claim</th><th>cases</th></tr>"]
    for (study, claim), rows in sorted(claims.items(), key=lambda kv: (STATES.index(claim_state(kv[1])), kv[0])):
        first = rows[0]
        about = sorted({s for r in rows for s in solvers_of(r)})
        verdicts = sorted({r["verdict"] for r in rows})
        commands = sorted({str(r.get("command") or "") for r in rows})
        commands = [c for c in commands if c.startswith("pcverify study")]
        group = "".join(f"<div><code>{e(c)}</code></div>" for c in commands[:1])
        parts.append(f"<tr class='claim' data-study='{e(study)}' data-solvers='{e(' '.join(about))}' "
                     f"data-verdicts='{e(' '.join(verdicts))}' data-state='{claim_state(rows)}'>"
                     f"<td class='claim'><b>{e(claim)}</b> <span class='ref'>{e(first['reference'])}</span> "
                     f"<a class='meta' href='#{anchor(study)}'>{e(study)}</a>"
                     f"<div class='statement'>{e(first['statement'])}</div>{_tolerance_line(rows)}{group}</td>"
                     f"<td><div class='cases'>{''.join(_case_chip(r) for r in rows)}</div></td></tr>")
    parts.append("</table></section>")
    return "".join(parts)


def data_table(df: pd.DataFrame, table_id: str) -> str:
    """A table for people: numbers with units and 4 digits, long text cut (full text on hover), at most
    MAX_TABLE_ROWS rows."""
    if df.empty:
        return f"<table id='{e(table_id)}' class='data'><tr><td>(no rows)</td></tr></table>"
    cols = list(df.columns)
    out = [f"<div class='scroll'><table id='{e(table_id)}' class='data'><tr>"
           + "".join(f"<th>{e(str(c))}</th>" for c in cols) + "</tr>"]
    for row in df.head(MAX_TABLE_ROWS).itertuples(index=False):
        tds = []
        for c, v in zip(cols, row, strict=True):
            text = "" if isinstance(v, float) and math.isnan(v) else cell(v, str(c))
            cls = f" class='{text}'" if c == "verdict" and text in STATES else ""
            tip = f" title='{e(text)}'" if len(text) > 24 else ""
            tds.append(f"<td{cls}{tip}>{e(text)}</td>")
        out.append("<tr>" + "".join(tds) + "</tr>")
    out.append("</table></div>")
    more = len(df) - MAX_TABLE_ROWS
    return "".join(out) + (f"<p class='meta'>{more} more rows in the CSV.</p>" if more > 0 else "")


def table_details(df: pd.DataFrame, href: str, table_id: str, shown: bool = False) -> str:
    """A table, collapsed unless `shown`: its name, size and CSV link in the summary line."""
    name = Path(href).stem
    opened = " open" if shown else ""
    return (f"<details class='table'{opened}><summary><b>{e(name)}</b> ({len(df)} rows × {len(df.columns)} columns) · "
            f"<a href='{e(href)}'>CSV</a></summary>{data_table(df, table_id)}</details>")


def image(path: Path, alt: str) -> str:
    data = base64.b64encode(path.read_bytes()).decode()
    return f"<img alt='{e(alt)}' src='data:image/png;base64,{data}'>"


def figure(folder: Path, study: str, name: str) -> str:
    """An embedded figure with links to its SVG and to the data it draws (NAME.json)."""
    stem = Path(name).stem
    links = [f"<a href='{e(study)}/{e(stem)}.{ext}'>{label}</a>" for ext, label in (("svg", "SVG"), ("json", "data"))
             if (folder / f"{stem}.{ext}").exists()]
    return (f"<figure id='{figure_id(study, name)}'>{image(folder / name, name)}<figcaption>{e(stem)} · "
            + " · ".join(links) + "</figcaption></figure>")


def study_section(folder: Path, man: dict[str, Any], records: list[dict[str, Any]], read: Any, extra: str = "") -> str:
    """A study: its verdict counts and command, then per group its figures and collapsed tables (a panel's shown
    open), then `extra` (the
    HTML of its mutants and sensitivity, if `pcverify mutate` or `pcverify sensitivity` ran)."""
    name = man["name"]
    mine = [r for r in records if r["study"] == name]
    counts = ", ".join(f"{n} {s}" for s, n in state_counts(mine).items())
    parts = [f"<section class='study' id='{anchor(name)}'><h2>{e(man['title'])}</h2>",
             f"<p class='meta'>study <b>{e(name)}</b> · {counts if mine else 'no claims'} · rerun: "
             f"<code>{e(man.get('rerun') or 'pcverify study ' + name)}</code></p>"]
    parts.append(notes_details(name, man.get("model_notes") or {}))
    if man.get("verdicts"):
        parts.append(table_details(read(folder / man["verdicts"]), f"{name}/{man['verdicts']}",
                                   anchor(name, "verdicts")))
    for sec in man["sections"]:
        parts.append(f"<h3 id='{anchor(name, sec['id'])}'>{e(sec['title'])}</h3>")
        parts += [figure(folder, name, f) for f in sec["figures"]]
        parts += [table_details(read(folder / t), f"{name}/{t}", anchor(name, Path(t).stem), bool(sec.get("open")))
                  for t in sec["tables"]]
        if sec.get("vtu"):
            parts.append(f"<p class='meta'>VTU point clouds (ParaView): {len(sec['vtu'])} files under "
                         f"<a href='{e(name)}/vtu/'>{e(name)}/vtu/</a></p>")
    parts.append(extra + "</section>")
    return "".join(parts)


def notes_details(study: str, notes: dict[str, list[str]]) -> str:
    """A study's model notes, per solver (collapsed): where the solvers it ran depart from their sources."""
    if not notes:
        return ""
    items = "".join(f"<li><b>{e(solver)}</b><ol>" + "".join(f"<li>{e(t)}</li>" for t in lines) + "</ol></li>"
                    for solver, lines in sorted(notes.items()))
    count = sum(len(v) for v in notes.values())
    verbs = ("departs", "chooses") if len(notes) == 1 else ("depart", "choose")
    return (f"<details class='notes' id='{anchor(study, 'model-notes')}'><summary>Model notes ({count}): where "
            f"{', '.join(sorted(notes))} {verbs[0]} from the source or {verbs[1]} what it leaves open</summary>"
            f"<ul>{items}</ul></details>")


def provenance_section(info: dict[str, str]) -> str:
    rows = "".join(f"<tr><th>{e(k)}</th><td>{e(v)}</td></tr>" for k, v in info.items())
    return f"<section id='provenance'><h2>Provenance</h2><table id='provenance-table'>{rows}</table></section>"


def page(nav: str, body: list[str]) -> str:
    return ("<!doctype html><html lang='en'><head><meta charset='utf-8'>"
            "<meta name='viewport' content='width=device-width,initial-scale=1'><title>pcverify report</title>"
            f"<style>{CSS}</style></head><body>{nav}<main>" + "\n".join(body)
            + f"</main><script>{SCRIPT}</script></body></html>")
