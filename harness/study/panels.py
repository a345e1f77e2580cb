"""Panels: the `[[panel]]` tables of a study file, quantities of several solvers side by side.

A panel reads values the groups already computed (a group's table, its rows, a column), one column per solver,
beside the reference each quantity stands on (a number or a value of another table) and its kind.  It is shown
in the report and never judged: what passes or fails is said by the claims.  This module reads and checks the
panels when the study loads (a table no group writes is a one-line error);
`pcverify.harness.judge.side_by_side` builds their tables.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from pcverify.harness.study.schema import PANEL, PANEL_ROW, STUDY, check_value, row_where
from pcverify.scene import SceneError


@dataclass(frozen=True)
class PanelRow:
    """One quantity of a panel: where its values are, how they are scaled, and its reference."""

    label: str
    table: str
    metric: str
    select: dict[str, Any]
    scale: float
    reference: float | None
    reference_table: str | None
    reference_metric: str
    reference_select: dict[str, Any]
    reference_kind: str


@dataclass(frozen=True)
class Panel:
    """Quantities of `solvers` side by side (a section of the report)."""

    id: str
    title: str
    solvers: tuple[str, ...]
    rows: tuple[PanelRow, ...]


def parse_panels(items: Any, where: str, group_ids: list[str]) -> list[Panel]:
    """Check every `[[panel]]` table against `schema.PANEL`; every table a row reads must be one a group writes
    (GROUP-KIND, GROUP one of `group_ids`): SceneError, one line, naming the panel, the row and the allowed."""
    out = []
    for number, item in enumerate(check_value(items, STUDY.field("panel"), where), 1):
        at = row_where(where, "panel", number, item, PANEL)
        rows = []
        for i, row in enumerate(item["row"], 1):
            row_at = row_where(at, "row", i, row, PANEL_ROW)
            for key in ("table", "reference_table"):
                name = row.get(key)
                if name is not None and not any(name.startswith(f"{g}-") for g in group_ids):
                    raise SceneError(f"{row_at}: {key} = {name!r} is not a table of this study; allowed: a group's "
                                     f"table, GROUP-KIND with GROUP one of {', '.join(group_ids) or '(no groups)'}")
            rows.append(PanelRow(row["label"], row["table"], row["metric"], dict(row["select"]), float(row["scale"]),
                                 None if row.get("reference") is None else float(row["reference"]),
                                 row.get("reference_table"), row["reference_metric"], dict(row["reference_select"]),
                                 row["reference_kind"]))
        out.append(Panel(item["id"], item.get("title", item["id"]), tuple(item["solvers"]), tuple(rows)))
    return out
