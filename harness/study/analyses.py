"""The analyses a study group can ask for (`analysis = ...`), as declarations.

An analysis says what its cells compute (a cell task), whether its cells are timed (run serially after a
warm-up) and which group options it reads (schema fields); how its cells' results become tables
(`pcverify.harness.judge.group_tables`) and figures (`pcverify.harness.report.group_figures`) is written there,
under the same name.  The study loader and the study-file schema look analyses up here; a new analysis is one
entry here and one in each of those two tables.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pcverify.harness.study.schema import Field
from pcverify.harness.study.stability import PROBE_KINDS
from pcverify.harness.study.tasks import SOLVE, TASKS, CellTask

# the figures a group can ask for by name (its `figures` list), drawn by `report.figures.GROUP_FIGURES`
GROUP_FIGURE_KINDS = ("edge-profiles", "render-3d", "history", "parameter")  # parameter: figure_y against figure_x


@dataclass(frozen=True)
class Analysis:
    """One kind of group analysis (see the module docstring)."""

    name: str
    description: str
    options: tuple[Field, ...] = ()  # the group keys it reads (`schema`: a group's fields by its analysis)
    serial: bool = False
    needs_field: bool = False  # its table's error column is the scene's reference field against each solution
    task: Callable[[dict[str, Any]], CellTask] = field(default=lambda options: SOLVE)


MIX_RUNS = Field("mix_runs", "bool", "draw timings of different timed passes side by side (false: the figure says "
                 "why it draws nothing)", default=False)

ANALYSES: dict[str, Analysis] = {a.name: a for a in (
    Analysis("table", "one row per cell: status and every summary scalar"),
    Analysis("convergence", "values or errors against h per solver sequence, fitted orders, Richardson and GCI",
             options=(
                 Field("quantities", "text", "summary quantities to follow", shape="list",
                       default=["volume_mean", "bulk_median"]),
                 Field("reference_table", "text", "an earlier group's fits table whose values are the reference"),
                 Field("reference_metric", "text", "the column of reference_table taken", default="extrapolated"),
                 Field("reference", "text", "self: also each sample set against the sequence's own finest level "
                       "(self-convergence: columns self.<set>.l2/linf, fits of reference self); scene: the scene's "
                       "reference only", choices=("scene", "self"), default="scene"),
                 Field("norms", "text", "error norms the convergence figure draws", shape="list",
                       choices=("l2", "linf"), default=["l2", "linf"]))),
    Analysis("timing", "CPU time of the solve against unknowns per solver (timed serially after a warm-up)",
             serial=True, options=(MIX_RUNS,)),
    Analysis("work-precision", "error against the solve's CPU time per solver (timed serially after a warm-up)",
             serial=True, needs_field=True,
             options=(Field("error", "text", "the error column (err.<error> of the cells)", default="nodes.l2"),
                      MIX_RUNS, Field("beside", "text", "earlier work-precision groups drawn as panels beside this one "
                                      "on the same CPU-seconds axis", shape="value or list"))),
    Analysis("stability", "measured time-step limits (probe = limit) or a stability map (probe = map)",
             options=(Field("probe", "text", "a limit per case, or a map over dt and the swept parameters",
                            choices=PROBE_KINDS, default="limit"),),
             task=lambda options: TASKS[f"stability-{options['probe']}"]),
)}

# what the study-file schema's registries name: each analysis's options, and the figure kinds
REGISTRIES = {"analyses": {name: a.options for name, a in ANALYSES.items()}, "figures": GROUP_FIGURE_KINDS}
