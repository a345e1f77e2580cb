"""The study-file reference in Markdown, rendered from the schema's declarations.

Every table of a study file and every key in it, with what a valid value is (in the words of the error lines),
its default and its description, comes from `schema` and from the group options each analysis declares
(`analyses`): the reference says what `pcverify study` accepts, because it is made of what the checks read.
docs/study-files.md carries it between `BEGIN` and `END`; tests/test_docs.py regenerates it and compares.
"""

from __future__ import annotations

import html
import json
from typing import Any

from pcverify.harness.study.analyses import ANALYSES, REGISTRIES
from pcverify.harness.study.schema import STUDY, Field, Table

BEGIN = "<!-- generated from harness/study/schema.py by `python tests/test_docs.py --regenerate`: edit the schema -->"
END = "<!-- end of the generated reference -->"


def study_file_reference() -> str:
    """The reference section of docs/study-files.md, from BEGIN to END: the top level of a study file, then each
    kind of table with the tables nested in it, then the options of each group analysis."""
    parts = [BEGIN, "", "## Reference", "", "### The top level", "", *_key_table(STUDY)]
    for field in STUDY.fields:
        if field.kind == "tables":
            parts += _table_section(field.table, "###", "", seen=set())
    return "\n".join([*parts, END]) + "\n"


def _table_section(table: Table, level: str, inside: str, seen: set[int]) -> list[str]:
    """A table's heading, its keys, what they must satisfy together, then the tables nested in it (each once)."""
    seen.add(id(table))
    heading = f"`{table.title}`" if table.title.startswith("[[") else f"`{table.title}` (in `{inside}`)"
    lines = ["", f"{level} {heading}", "", *_key_table(table)]
    if table.one_of:
        lines += ["", f"Exactly one of {_names(table.one_of)}."]
    unique = [f.name for f in table.fields if f.unique]
    if unique:
        lines += ["", f"No two `{table.title}` tables have the same {_names(unique)}."]
    if table.variant:
        lines += _variant_section(table, level + "#")
    for field in table.fields:
        for nested in _nested(field):
            if id(nested) not in seen:
                lines += _table_section(nested, level + "#", table.title, seen)
    return lines


def _variant_section(table: Table, level: str) -> list[str]:
    """The keys a variant field adds: a group's analysis and the options each analysis reads."""
    chosen = table.field(table.variant)
    lines = ["", f"{level} The options of each `{table.variant}`", "",
             f"Besides the keys above, a `{table.title}` table takes the options of its `{table.variant}`:"]
    for name, options in REGISTRIES[chosen.registry].items():
        lines += ["", f"- `{table.variant} = \"{name}\"`: {_text(ANALYSES[name].description)}"
                  + ("" if options else "; no options.")]
        if options:
            lines += ["", *(f"  {row}" for row in _key_table(Table(name, tuple(options))))]
    return lines


def _nested(field: Field) -> list[Table]:
    """The tables declared inside a field: a record's or a list's table, or an alternative's."""
    tables = [field.table] if field.kind in ("record", "tables") and field.table is not None else []
    return tables + [a.table for a in field.alternatives if a.table is not None]


def _key_table(table: Table) -> list[str]:
    """One row per key: its name, what a valid value is, its default (or required) and what it means."""
    rows = ["| key | value | default | what it is |", "|---|---|---|---|"]
    for f in table.fields:
        default = "required" if f.required else "—" if f.default is None else f"`{_toml(f.default)}`"
        rows.append(f"| `{f.name}` | {_text(f.allowed(REGISTRIES))} | {default} | {_text(f.description)} |")
    return rows


def _toml(value: Any) -> str:
    """A default as it is written in a study file."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {_toml(v)}" for k, v in value.items()) + " }" if value else "{}"
    return json.dumps(value) if isinstance(value, str) else str(value)


def _text(words: str) -> str:
    """Words inside a Markdown table cell: no HTML tags, no column breaks."""
    return html.escape(words, quote=False).replace("|", "\\|")


def _names(names: Any) -> str:
    quoted = [f"`{n}`" for n in names]
    return quoted[0] if len(quoted) == 1 else ", ".join(quoted[:-1]) + " and " + quoted[-1]
