"""Claims: the `[[claim]]` tables of a study file as checkable statements about its results.

A claim names a table, its rows (`select`), a column (`metric`), how rows combine (`aggregate`), a target and
tolerance with its sense, the kind of reference the number stands on, the uncertainty to weigh it with, and
which cell statuses its cases may stand on.  `pcverify.harness.judge.verdict` judges claims on tables; this
module only reads and checks them (one line naming the claim and the field, before anything runs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from pcverify.harness.spec.schema import CLAIM, STUDY, check_value, row_where
from pcverify.scene import SceneError

SPREAD = "spread"  # uncertainty = the standard error of the mean over a case's replica rows


@dataclass(frozen=True)
class Claim:
    """One checkable statement about a study's results."""

    id: str
    text: str
    table: str
    metric: str
    reference: str
    tolerance: float
    target: float = 0.0
    select: dict[str, Any] = field(default_factory=dict)
    aggregate: str = "max"
    absolute: bool = False  # compare |value| (e.g. signed differences) with the target
    per: str = ""
    against: dict[str, Any] = field(default_factory=dict)
    against_table: str = ""  # default: the claim's own table
    against_metric: str = ""  # default: the claim's metric
    uncertainty: float | str = math.nan  # a number, a column aggregated like the metric, or "spread"
    sense: str = "within"  # within: |value - target| <= tol; at-most: value <= target + tol; at-least: >= target - tol
    statuses: tuple[str, ...] = ("ok",)  # cell statuses a case may stand on
    allow_skipped: bool = False  # a case whose cells were all skipped is not-applicable instead of fail


def parse_claims(items: list[dict[str, Any]], where: str) -> list[Claim]:
    """The `[[claim]]` tables of a study file as claims, checked against `schema.CLAIM` before anything runs
    (SceneError, one line, naming the claim, the field and the allowed values)."""
    check_value(items, STUDY.field("claim"), where)
    for number, item in enumerate(items, 1):
        if item.get("uncertainty") == SPREAD and item.get("aggregate", "max") != "mean":
            at = row_where(where, "claim", number, item, CLAIM)
            raise SceneError(f"{at}: uncertainty=\"spread\" is the standard error of a mean; allowed: it with "
                             "aggregate = \"mean\"")
    return [Claim(**item | ({"statuses": tuple(item["statuses"])} if "statuses" in item else {})) for item in items]
