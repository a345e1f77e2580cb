"""Claims: the `[[claim]]` tables of a study file as checkable statements about its results.

A claim names a table, its rows (`select`), a column (`metric`), how rows combine (`aggregate`), a target and
tolerance with its sense, the kind of reference the number stands on, the uncertainty to weigh it with, and
which cell statuses its cases may stand on.  `pcverify.harness.judge.verdict` judges claims on tables; this
module only reads and checks them (one line naming the claim and the field, before anything runs).

A target is a number, `"reference:NAME"` (a scalar of the scene's reference) or an expression of the resolution
(n, refine, a, h), the scene's numeric parameters, its material's constants, the solver parameters the group's
cells share, the values the claim selects and reference scalars (`"sigma_c / k"`): computed, not pasted.
It is evaluated at every (n, refine) of the claim's group when the study loads (a bad name fails there).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pcverify.harness.study.expressions import evaluate
from pcverify.harness.study.schema import CLAIM, STUDY, check_value, row_where
from pcverify.scene import SceneError, is_real, shown

SPREAD = "spread"  # uncertainty = the standard error of the mean over a case's replica rows
REFERENCE = "reference:"  # a target naming a scalar of the scene's reference
# what a text target may name at each (n, refine) of its group: (the reference's scalars, the other names)
Levels = dict[tuple[int, int], tuple[dict[str, float], dict[str, float]]]


@dataclass(frozen=True)
class Claim:
    """One checkable statement about a study's results."""

    id: str
    text: str
    table: str
    metric: str
    reference: str
    tolerance: float = 0.0  # absolute, added to tolerance_rel x |target|
    tolerance_rel: float = 0.0  # relative to the target
    tolerance_basis: str = ""  # "derived: ..." or "measured: ... (Nx)": where the tolerance comes from
    target: float | str = CLAIM.field("target").default  # a number, "reference:NAME" or an expression (above)
    select: dict[str, Any] = field(default_factory=dict)
    aggregate: str = CLAIM.field("aggregate").default  # the defaults of a claim built here are the schema's
    absolute: bool = CLAIM.field("absolute").default  # compare |value| (e.g. signed differences) with the target
    per: tuple[str, ...] = ()  # the columns whose combinations of values make the cases
    against: dict[str, Any] = field(default_factory=dict)
    against_table: str = ""  # default: the claim's own table
    against_metric: str = ""  # default: the claim's metric
    uncertainty: float | str = math.nan  # a number, a column aggregated like the metric, or "spread"
    sense: str = CLAIM.field("sense").default  # within: |value - target| <= tol; at-most: <= target + tol; ...
    statuses: tuple[str, ...] = tuple(CLAIM.field("statuses").default)  # cell statuses a case may stand on
    at_error: float = 0.0  # a cost claim: the metric (a cost) at this error, log-log interpolated (judge/cost.py)
    error_metric: str = ""  # the error column at_error reads (default: the table's only err.* column)
    allow_skipped: bool = CLAIM.field("allow_skipped").default  # all cells skipped: not-applicable, not fail
    targets: tuple[tuple[int, int, float], ...] = ()  # a text target's value at each (n, refine) of its group


def parse_claims(items: list[dict[str, Any]], where: str, levels: Callable[[str], Levels | None] = lambda t: None
                 ) -> list[Claim]:
    """The `[[claim]]` tables of a study file as claims, checked against `schema.CLAIM` before anything runs
    (SceneError, one line, naming the claim, the field and the allowed values); `levels(table)`: what a text
    target on that table may name (None: no group makes the table)."""
    claims = []
    for number, item in enumerate(check_value(items, STUDY.field("claim"), where), 1):
        at = row_where(where, "claim", number, item, CLAIM)
        if item.get("uncertainty") == SPREAD and item["aggregate"] != "mean":
            raise SceneError(f"{at}: uncertainty=\"spread\" is the standard error of a mean; allowed: it with "
                             "aggregate = \"mean\"")
        if "tolerance" not in item and "tolerance_rel" not in item:
            raise SceneError(f"{at}: tolerance is missing; allowed: a tolerance (absolute), a tolerance_rel "
                             "(relative to the target) or both")
        per = item.get("per", ())
        claim = Claim(**item | {"statuses": tuple(item["statuses"]), "per": (per,) if isinstance(per, str) else
                                tuple(per)})
        if isinstance(claim.target, str):
            chosen = {k: v for k, v in claim.select.items() if is_real(v)}  # a value the claim's rows all have
            claim = dataclasses.replace(claim, targets=_targets(claim.target, levels(claim.table), chosen, at))
        claims.append(claim)
    return claims


def bound(claim: Claim, target: float) -> float:
    """The claim's tolerance at a target: the absolute one plus the relative one times |target|."""
    return claim.tolerance + claim.tolerance_rel * abs(target)


def _targets(text: str, levels: Levels | None, chosen: dict[str, float], at: str
             ) -> tuple[tuple[int, int, float], ...]:
    """A text target's value at each (n, refine) of its group (SceneError naming the claim and the field)."""
    if not levels:
        raise SceneError(f"{at}: target={shown(text)} is not valid; allowed: a number (no group makes the table)")
    name, out = text.removeprefix(REFERENCE), []
    for (n, refine), (scalars, names) in sorted(levels.items()):
        if name != text and name not in scalars:
            raise SceneError(f"{at}: target={shown(text)} is not valid; allowed: reference:NAME, NAME one of the "
                             f"scene's reference scalars ({', '.join(scalars) or 'it has none'})")
        try:
            value = scalars[name] if name != text else evaluate("target", text, chosen | names | scalars)
            out.append((n, refine, value))
        except SceneError as exc:
            raise SceneError(f"{at}: {exc}") from None
    return tuple(out)
