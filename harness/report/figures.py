"""Report figures (PNG and SVG): convergence, cost, work-precision, stability, edge profiles, 3-D renders,
benchmarks.

Each function takes tables or cached results and a path without suffix, and writes `path.png`, `path.svg`
and `path.json` (what the figure draws: every series with its data, every legend entry, and how many
drawn points a legend covers); it returns True when it drew something.  A series identical to one already
drawn on the same axes is not drawn again: its label joins the first one's.  Legends sit outside the
data.  Nothing here runs a solver.  `GROUP_FIGURES` is the registry of the figures a study group can ask
for by name (its `figures` list).
"""

from __future__ import annotations

import inspect
import io
import json
import math
import textwrap
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.collections import PathCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from mpl_toolkits.mplot3d import Axes3D  # noqa: E402
from PIL import Image  # noqa: E402

from pcverify.harness.judge.tables import spacing, stored_errors  # noqa: E402
from pcverify.harness.run.files import atomic_write  # noqa: E402
from pcverify.harness.study.catalogue import get_spec  # noqa: E402

EDGES = ("front_top_edge", "bottom_back_edge")
CONTINUUM_STYLES = tuple(dict(lw=2.0, color=c, ls=ls, alpha=0.75)
                         for c, ls in (("k", "-"), ("0.45", "--"), ("0.25", ":"), ("0.6", "-.")))
SAME_RTOL = 1e-9  # two series whose points agree to this relative tolerance are one series


def _wrap(title: str, fig: Any, fontsize: float = 9.0) -> str:
    """A title wrapped to the figure's width (about 0.5 em per character)."""
    width = max(30, int(fig.get_figwidth() * 72 / (0.52 * fontsize)))
    return "\n".join(textwrap.wrap(title, width))


def same_series(x1: Any, y1: Any, x2: Any, y2: Any) -> bool:
    """Whether two series draw the same points (NaN where the other has NaN, else equal to SAME_RTOL)."""
    a = [np.asarray(v, dtype=float).ravel() for v in (x1, y1, x2, y2)]
    if a[0].shape != a[2].shape or a[1].shape != a[3].shape:
        return False
    return all(np.allclose(p, q, rtol=SAME_RTOL, atol=0.0, equal_nan=True) for p, q in ((a[0], a[2]), (a[1], a[3])))


def plot_once(ax: Any, x: Any, y: Any, fmt: str, label: str, **style: Any) -> Any:
    """ax.plot, unless a labelled series with the same points is on `ax` already: then its label gains
    " = label" and nothing is drawn (identical series drawn once).  Returns the line that shows the data."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    for line in ax.get_lines():
        old = line.get_label()
        if not old.startswith("_") and same_series(line.get_xdata(), line.get_ydata(), x, y):
            line.set_label(f"{old} = {label}")
            return line
    return ax.plot(*((x, y, fmt) if fmt else (x, y)), label=label, **style)[0]


def legend_outside(ax: Any, fontsize: float = 6.5) -> None:
    """The legend to the right of the axes, outside the data (nothing when no series is labelled)."""
    handles, labels = ax.get_legend_handles_labels()
    if handles:
        ax.legend(handles, labels, fontsize=fontsize, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                  borderaxespad=0.0)


def _visible_points(xy: np.ndarray, marker: bool, line: bool, logx: bool, logy: bool) -> np.ndarray:
    """Mask of the points of a series that appear on the canvas: finite (and positive on a log axis),
    and either marked or the end of a drawn segment."""
    ok = np.all(np.isfinite(xy), axis=1) if xy.size else np.zeros(0, bool)
    if logx and xy.size:
        ok &= xy[:, 0] > 0
    if logy and xy.size:
        ok &= xy[:, 1] > 0
    if marker:
        return ok
    seg = ok[:-1] & ok[1:] if line and ok.size > 1 else np.zeros(max(ok.size - 1, 0), bool)
    shown = np.zeros_like(ok)
    shown[:-1] |= seg
    shown[1:] |= seg
    return shown


def _series(ax: Any) -> list[tuple[Any, dict[str, Any], np.ndarray]]:
    """(artist, description, display coordinates of its visible points) of every line and point set of `ax`."""
    logx, logy = ax.get_xscale() == "log", ax.get_yscale() == "log"
    out = []
    for artist in ax.get_children():
        if isinstance(artist, Line2D):
            xy = np.column_stack([np.asarray(artist.get_xdata(), float), np.asarray(artist.get_ydata(), float)])
            marker = artist.get_marker() not in (None, "", " ", "None", "none")
            line = artist.get_linestyle() not in ("None", "", " ", "none") and artist.get_linewidth() > 0
            transform = artist.get_transform()
            kind = "line"
        elif isinstance(artist, PathCollection):
            xy = np.asarray(artist.get_offsets(), dtype=float).reshape(-1, 2)
            marker, line, transform, kind = True, False, artist.get_offset_transform(), "points"
        else:
            continue
        if isinstance(ax, Axes3D):
            logx = logy = False
        vis = _visible_points(xy, marker, line, logx, logy)
        pix = transform.transform(np.where(np.isfinite(xy), xy, 0.0)[vis]) if vis.any() else np.zeros((0, 2))
        desc = {"label": artist.get_label(), "kind": kind, "marker": marker, "line": line,
                "visible_points": int(vis.sum()),
                "x": [None if not math.isfinite(v) else float(v) for v in xy[:, 0]],
                "y": [None if not math.isfinite(v) else float(v) for v in xy[:, 1]]}
        out.append((artist, desc, pix))
    return out


def describe(fig: Any) -> dict[str, Any]:
    """What a drawn figure shows: per axes its labels, scales, series (data, visible point count) and legend
    entries, and how many visible data points (of any axes) each legend covers."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    axes = [(ax, _series(ax)) for ax in fig.axes]
    points = [pix for _, series in axes for _, _, pix in series]
    every = np.vstack(points) if points else np.zeros((0, 2))
    out = []
    for ax, series in axes:
        legend = ax.get_legend()
        entry: dict[str, Any] = {"title": ax.get_title(), "xlabel": ax.get_xlabel(), "ylabel": ax.get_ylabel(),
                                 "xscale": ax.get_xscale(), "yscale": ax.get_yscale(),
                                 "series": [d for _, d, _ in series], "legend": [], "legend_covers": 0}
        if legend is not None:
            entry["legend"] = [t.get_text() for t in legend.get_texts()]
            box = legend.get_window_extent(renderer)
            inside = ((every[:, 0] >= box.x0) & (every[:, 0] <= box.x1) & (every[:, 1] >= box.y0)
                      & (every[:, 1] <= box.y1)) if every.size else np.zeros(0, bool)
            entry["legend_covers"] = int(inside.sum())
        out.append(entry)
    return {"suptitle": fig.get_suptitle(), "axes": out}


PNG_DPI = 100


def _save(fig: Any, path: Path, title: str | None = None, layout: str = "constrained") -> bool:
    """Title the figure (`title`, wrapped to its width; None: the axes carry their own), lay out
    (constrained: room for the title and for legends outside the axes; "tight" for 3-D panels with colour
    bars), describe (path.json) and write path.png (a 256-colour palette: a third of the bytes, the same
    picture) and path.svg."""
    if title is not None:
        fig.suptitle(_wrap(title, fig), fontsize=9)
    if layout == "tight":
        title = fig.get_suptitle()
        room = (0.17 * (title.count("\n") + 1) + 0.08) / fig.get_figheight() if title else 0.0
        fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - room))
    else:
        fig.set_layout_engine(layout)
    try:
        atomic_write(path.with_suffix(".json"), json.dumps(describe(fig)))
        # describe drew the figure on its Agg canvas: at 100 dpi that picture is the PNG, not drawn again
        drawn = Image.fromarray(np.asarray(fig.canvas.buffer_rgba())) if fig.dpi == PNG_DPI else None
        atomic_write(path.with_suffix(".svg"), lambda fh: fig.savefig(fh, format="svg"))
        if drawn is None:
            buffer = io.BytesIO()
            fig.savefig(buffer, format="png", dpi=PNG_DPI)
            drawn = Image.open(buffer)
    finally:
        plt.close(fig)
    with drawn as im:
        small = im.convert("RGB").quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    atomic_write(path.with_suffix(".png"), lambda fh: small.save(fh, format="PNG", optimize=True))
    return True


def log_axes(ax: Any, xlabel: str, ylabel: str, logx: bool = True, legend: float | None = 6.5) -> None:
    """The skeleton of every log-log figure (semi-log in y when not `logx`): log scales, the axis labels, a
    grid on major and minor ticks, and the legend outside the data (`legend`: its font size; None: none)."""
    if logx:
        ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(True, which="both", alpha=0.3)
    if legend is not None:
        legend_outside(ax, legend)


def _lines(ax: Any, groups: Any, x: str, y: str, label: Any = lambda name, seq: str(name), along: bool = True
           ) -> None:
    """One marked line ("o-") per group of a DataFrame groupby, points in the order of `x` (as given when not
    `along`), labelled `label(name, group)`."""
    for name, seq in groups:
        seq = seq.sort_values(x) if along else seq
        plot_once(ax, seq[x], seq[y], "o-", label(name, seq))


def _label(r: dict[str, Any], varying: list[str]) -> str:
    params = r.get("solver_params") or {}
    extra = " ".join(f"{k}={params[k]:g}" if isinstance(params.get(k), float) else f"{k}={params.get(k)}"
                     for k in varying if k in params)
    return f"{r['solver']} {extra}".strip()


def _varying(results: list[dict[str, Any]]) -> list[str]:
    keys: dict[str, set[str]] = {}
    for r in results:
        for k, v in (r.get("solver_params") or {}).items():
            keys.setdefault(k, set()).add(repr(v))
    return sorted(k for k, vals in keys.items() if len(vals) > 1)


SHOWN = ("ok", "non-stationary", "defect")  # runs that completed: their fields are drawn, status in the label


def _shown(r: dict[str, Any], sample: str) -> bool:
    return r.get("status") in SHOWN and sample in (r.get("samples") or {})


def is_particle(result: dict[str, Any]) -> bool:
    """Whether a result comes from a particle solver (the solver's declared kind)."""
    return result.get("solver_kind") == "particle"


def convergence(levels: pd.DataFrame, columns: list[str], path: Path, title: str,
                fits: pd.DataFrame | None = None) -> bool:
    """log-log error (or value) against h, one line per solver sequence and column, with the fitted order.

    Columns of one sequence with the same values (e.g. the edges' error equal to the nodes' on a 1-D
    solution) are one line, labelled with all their names.  A line draws the levels where its column is finite
    and positive (two or more).  A self-convergence column (self.*) is drawn as what its order is fitted on, the
    successive differences |u_k - u_k+1| (its `_next` column, at the coarser level's h), labelled "successive
    differences"; the values are absolute, in the field's own units (T/t_max for heat)."""
    orders = {}
    if fits is not None and not fits.empty and "order" in fits:
        orders = {(r.solver, r.params, r.quantity): r.order for r in fits.itertuples() if pd.notna(r.order)}
    fig, ax = plt.subplots(figsize=(9.5, 4))
    for (solver, params), seq in levels.groupby(["solver", "params"], sort=False):
        seq = seq.sort_values("h")
        drawn: list[tuple[list[str], np.ndarray]] = []
        for col in columns:
            if col not in seq:
                continue
            drawn_col = f"{col}_next" if col.startswith("self.") and f"{col}_next" in seq else col
            y = pd.to_numeric(seq[drawn_col], errors="coerce").abs().to_numpy(float)
            shown = np.isfinite(y) & (y > 0)
            if shown.sum() < 2 or (not col.startswith("self.") and not shown.all()):
                continue
            y = np.where(shown, y, np.nan)
            same = next((d for d in drawn if same_series(d[1], d[1], y, y)), None)
            if same is None:
                drawn.append(([col], y))
            else:
                same[0].append(col)
        for cols, y in drawn:
            order = orders.get((solver, params, cols[0]))
            slope = f" (fitted order {order:.2f})" if order is not None else ""
            kind = "successive differences " if cols[0].startswith("self.") else ""
            shown = np.isfinite(y)
            plot_once(ax, seq["h"].to_numpy(float)[shown], y[shown], "o--" if kind else "o-",
                      f"{solver} {params} {kind}{_columns([c.removeprefix('self.') for c in cols])}{slope}"
                      .replace("  ", " "))
    errors = any(c.endswith(("l2", "linf")) or c.startswith("err.") for c in columns)
    log_axes(ax, "h [m]", "error or difference (absolute, field units)" if errors else "|value|")
    return _save(fig, path, title)


def _columns(cols: list[str]) -> str:
    """Names of columns drawn as one line: "nodes=front_top_edge.linf" when they share the part after the
    last dot, else joined by " = "."""
    heads, _, tails = zip(*(c.rpartition(".") for c in cols), strict=True)
    if len(cols) > 1 and all(heads) and len(set(tails)) == 1:
        return "=".join(heads) + "." + tails[0]
    return " = ".join(cols)


def mixed_runs(df: pd.DataFrame) -> str:
    """Why the timings of `df` should not be drawn side by side ("" when they may): rows of more than one timed
    pass (another day, machine or load), or rows without a pass's stamp."""
    runs = sorted(set(df["run"].astype(str))) if "run" in df else ["unknown"]
    if len(runs) == 1 and runs[0] != "unknown":
        return ""
    if "unknown" in runs:
        return "some timings carry no timed pass's stamp (computed by an older pcverify)"
    when = sorted({f"{r.machine} at {r.started}" for r in df.itertuples()})
    return f"the timings come from {len(runs)} timed passes ({'; '.join(when)})"


def refusal(path: Path, title: str, why: str) -> bool:
    """A figure that says why it draws nothing (timings of different passes are not compared unless asked)."""
    fig, ax = plt.subplots(figsize=(9, 1.8))
    ax.axis("off")
    text = (f"Not drawn: {why}. Rerun the group's cells in one pass (pcverify study STUDY --group GROUP "
            "--rerun), or set mix_runs = true in the group to draw them anyway.")
    ax.text(0.5, 0.5, textwrap.fill(text, 110), ha="center", va="center", fontsize=9)
    return _save(fig, path, title)


def cost(df: pd.DataFrame, path: Path, title: str, mix_runs: bool = False) -> bool:
    """CPU seconds of the solve against unknowns per solver (one timed pass unless `mix_runs`)."""
    why = "" if mix_runs else mixed_runs(df)
    if why:
        return refusal(path, title, why)
    fig, ax = plt.subplots(figsize=(8, 4))
    _lines(ax, df.groupby("solver"), "unknowns", "cpu_s")
    log_axes(ax, "unknowns (free degrees of freedom)", "CPU time of the solve [s]")
    return _save(fig, path, title)


def work_precision(df: pd.DataFrame, error: str, path: Path, title: str, mix_runs: bool = False,
                   beside: list[tuple[str, pd.DataFrame]] = ()) -> bool:
    """Error against the CPU seconds of the solve (left: set-up and kernel; right: the kernel alone, for the
    solvers that report it), one line per solver: one axis for particle and continuum solvers alike, from one
    timed pass unless `mix_runs`.  With `beside` (other groups' work-precision tables, by group id), one panel
    per group (this one first, titled by the figure's file name) instead, all on one shared CPU-seconds axis:
    solvers that share no scene compared on cost."""
    if df.empty:
        return False
    why = "" if mix_runs else mixed_runs(pd.concat([df, *(b for _, b in beside)], ignore_index=True))
    if why:
        return refusal(path, title, why)
    if beside:
        panels = [(path.name, df), *beside]
        fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels) + 2.5, 4), sharex=True, squeeze=False)
        for ax, (name, part) in zip(axes[0], panels, strict=True):
            _lines(ax, part.dropna(subset=["cpu_s", error]).groupby("solver"), "cpu_s", error)
            log_axes(ax, "CPU time of the solve [s]", error)
            ax.set_title(name, fontsize=9)
        return _save(fig, path, title)
    fig, (left, right) = plt.subplots(1, 2, figsize=(12, 4))
    _lines(left, df.dropna(subset=["cpu_s"]).groupby("solver"), "cpu_s", error)
    _lines(right, df.dropna(subset=["kernel_s"]).groupby("solver"), "kernel_s", error)
    log_axes(left, "CPU time of the solve [s]", error, legend=None)
    log_axes(right, "CPU time of its kernel (time loop or linear solve) [s]", error)
    return _save(fig, path, title)


PHASE_MARKERS = {"design": "o", "local": "s", "replica": "^", "sensitivity": "D"}


def calibration_trace(trace: pd.DataFrame, path: Path, title: str) -> bool:
    """Objective against evaluation (log scale), by phase, the best so far as a line; failed sets as x at the
    top (they have no objective)."""
    if trace.empty:
        return False
    fig, ax = plt.subplots(figsize=(9, 4))
    ok = trace[trace["status"] == "ok"]
    for phase, part in ok.groupby("phase", sort=False):
        ax.plot(part["evaluation"], part["objective"], PHASE_MARKERS.get(phase, "o"), ms=5, label=phase, alpha=0.8)
    if "best_so_far" in trace and trace["best_so_far"].notna().any():
        ax.plot(trace["evaluation"], trace["best_so_far"], "k-", lw=1, label="best so far (search)")
    bad = trace[trace["status"] != "ok"]
    if not bad.empty:
        top = ok["objective"].max() if not ok.empty else 1.0
        ax.plot(bad["evaluation"], np.full(len(bad), top * 1.5), "rx", label="failed set (" + ", ".join(
            sorted(bad["status"].unique())) + ")")
    log_axes(ax, "evaluation", "objective (calibrated on)", logx=False)
    return _save(fig, path, title)


def calibration_work_precision(trace: pd.DataFrame, path: Path, title: str) -> bool:
    """Objective against the wall time and the work counter of each evaluated parameter set (ok ones)."""
    ok = trace[trace["status"] == "ok"] if not trace.empty else trace
    if ok.empty:
        return False
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4))
    for phase, part in ok.groupby("phase", sort=False):
        marker = PHASE_MARKERS.get(phase, "o")
        left.plot(part["wall_s"], part["objective"], marker, label=phase, alpha=0.8)
        right.plot(part["work"], part["objective"], marker, label=phase, alpha=0.8)
    log_axes(left, "wall time of the set's cells [s]", "objective (calibrated on)")
    log_axes(right, f"work ({ok['work_kind'].iloc[0]})", "objective (calibrated on)")
    return _save(fig, path, title)


def calibration_validation(table: pd.DataFrame, tolerance: float, path: Path, title: str) -> bool:
    """Error per cell at the calibrated and at the default parameters (failed runs marked), the tolerance."""
    if table.empty:
        return False
    fig, ax = plt.subplots(figsize=(9, 4))
    x = np.arange(len(table))
    for offset, col, label in ((-0.2, "default", "default parameters"), (0.2, "calibrated", "calibrated")):
        err = pd.to_numeric(table[f"{col}_error"], errors="coerce").to_numpy(float)
        ax.bar(x + offset, np.where(np.isfinite(err), err, 0.0), 0.4, label=label)
        for xi, e, st in zip(x, err, table[f"{col}_status"], strict=True):
            if not np.isfinite(e):
                ax.annotate(str(st), (xi + offset, 0), rotation=90, fontsize=6, ha="center", va="bottom")
    if np.isfinite(tolerance):
        ax.axhline(tolerance, color="k", ls="--", lw=1, label=f"tolerance {tolerance:g}")
    ax.set_xticks(x, [f"{r}: {c}" for r, c in zip(table["role"], table["cell"], strict=True)], rotation=30,
                  ha="right", fontsize=6)
    ax.set_ylabel("error")
    ax.set_yscale("symlog", linthresh=1e-3)
    legend_outside(ax)
    return _save(fig, path, title)


def edge_profiles(results: list[dict[str, Any]], path: Path, title: str) -> bool:
    """The paper's Fig. 9: relative value along the two edges, particle polylines against continuum curves.

    One row of panels per lattice n; one line per parameter set (e.g. per damping value); the legend of a
    row beside its right panel.
    """
    ok = [r for r in results if all(_shown(r, e) for e in EDGES)]
    if not ok:
        return False
    ns = sorted({r["n"] for r in ok})
    varying = _varying(ok)
    fig, axes = plt.subplots(len(ns), 2, figsize=(12, 2.8 * len(ns)), squeeze=False)
    for row, n in enumerate(ns):
        for col, edge in enumerate(EDGES):
            ax = axes[row, col]
            continuum = iter(CONTINUUM_STYLES)
            for r in (r for r in ok if r["n"] == n):
                pts = np.asarray(r["samples"][edge]["points"], float)
                vals = np.asarray(r["samples"][edge]["values"], float)
                style = dict(marker="o", ms=3, lw=1) if is_particle(r) else next(continuum, CONTINUUM_STYLES[0])
                label = _label(r, varying) + ("" if is_particle(r) else f" refine={r['refine']}")
                label += "" if r["status"] == "ok" else f" ({r['status']})"
                plot_once(ax, pts[:, 2] * 1e3, vals, "", label, **style)
            ax.set_title(f"n = {n}: {edge.replace('_', ' ')}", fontsize=8)
            ax.set_xlabel("z [mm]")
            ax.set_ylabel("relative value")
            ax.grid(True, alpha=0.3)
        _share_legend(axes[row, 0], axes[row, 1])
    return _save(fig, path, title)


def _share_legend(source: Any, target: Any) -> None:
    """One legend for a row of panels drawing the same series: the labels of `target` (merged where a
    panel drew two series as one) and of `source`, outside `target`."""
    labels = {line.get_label(): line for line in target.get_lines() if not line.get_label().startswith("_")}
    listed = {part for k in labels for part in k.split(" = ")}
    for line in source.get_lines():
        lab = line.get_label()
        if not lab.startswith("_") and not set(lab.split(" = ")) <= listed:
            labels[lab] = line
            listed |= set(lab.split(" = "))
    if labels:
        target.legend(list(labels.values()), list(labels), fontsize=6, loc="upper left", bbox_to_anchor=(1.02, 1.0),
                      borderaxespad=0.0)


def render_3d(results: list[dict[str, Any]], path: Path, title: str) -> bool:
    """Particles coloured by their relative value (the paper's Figs. 2-4), or by the quantity their solver
    reports (e.g. the friction heat received), one panel per n."""
    ok = [r for r in results if is_particle(r) and _shown(r, "nodes")]
    first: dict[int, dict[str, Any]] = {}
    for r in ok:
        first.setdefault(r["n"], r)
    if not first:
        return False
    cols = min(3, len(first))
    rows = -(-len(first) // cols)
    fig = plt.figure(figsize=(4.2 * cols, 4.0 * rows + 0.4))
    for k, (n, r) in enumerate(sorted(first.items())):
        ax = fig.add_subplot(rows, cols, k + 1, projection="3d")
        pts = np.asarray(r["samples"]["nodes"]["points"], float) * 1e3
        vals = np.asarray(r["samples"]["nodes"]["values"], float)
        sc = ax.scatter(pts[:, 0], pts[:, 2], pts[:, 1], c=vals, cmap="inferno", s=40, vmin=0.0,
                        vmax=max(1.0, float(np.nanmax(vals))), depthshade=False)
        ax.set_xlabel("x [mm]", fontsize=7)
        ax.set_ylabel("z [mm]", fontsize=7)
        ax.set_zlabel("y [mm]", fontsize=7)
        ax.set_box_aspect((1, 3, 1))
        ax.set_title(f"{r['solver']} n={n} ({len(vals)} particles), {r['status']}", fontsize=8)
        quantity = r.get("quantity") or "T/t_max"
        fig.colorbar(sc, ax=ax, shrink=0.6, label="relative hotness" if quantity == "T/t_max" else quantity)
    return _save(fig, path, title, layout="tight")


STATUS_STYLE = {"ok": ("o", "tab:green"), "unstable": ("x", "tab:red"), "defect": ("s", "tab:orange"),
                "non-stationary": ("^", "tab:blue"), "failed": ("D", "tab:purple")}


def _case_label(keys: list[str], values: tuple[Any, ...]) -> str:
    """"n=2, D=0.01 a" for a group of measurements (NaN values left out)."""
    names = {"drive_amplitude": ("D", " a")}
    parts = []
    for key, v in zip(keys, values, strict=True):
        if isinstance(v, float) and math.isnan(v):
            continue
        name, unit = names.get(key, (key, ""))
        parts.append(f"{name}={v:g}{unit}" if isinstance(v, float) else f"{name}={v}{unit}")
    return ", ".join(parts)


def _limit_panel(ax: Any, part: pd.DataFrame, info: dict[str, str]) -> None:
    """One probe's panel: the theory's limit at each case, every measured limit (bounds marked as
    such), and the linear-discrete limit where the probe computed one, against the probe's x axis."""
    x = info["x_axis"]
    part = part.sort_values(x)
    theory = part[[x, "safety_theory"]].drop_duplicates().sort_values(x)
    plot_once(ax, theory[x], theory["safety_theory"], "k-", info["theory_label"], marker="_", ms=10, lw=1.5)
    groups = [g for g in ("n", "drive_amplitude") if g != x]
    verdict = part.get("verdict", pd.Series("bisected", index=part.index)).fillna("bisected").astype(str)
    bisected = part[verdict == "bisected"]
    for values, seq in bisected.groupby(groups, dropna=False, sort=True):
        values = values if isinstance(values, tuple) else (values,)
        label = f"measured {_case_label(groups, values)}".strip()
        plot_once(ax, seq[x], seq["measured_safety"], "o--", label, ms=5)
    bounds = {"stable up to": ("^", "lower bound: stable up to ratio_hi"),
              "unstable at every": ("v", "no time-step limit: unstable at every dt (drawn at ratio_lo)")}
    for start, (marker, label) in bounds.items():
        pick = part[verdict.str.startswith(start)]
        if not pick.empty:
            plot_once(ax, pick[x], pick["measured_safety"], marker, label, color="tab:red", ms=7, ls="none")
    if "linear_safety" in part and part["linear_safety"].notna().any():
        lin = part.dropna(subset=["linear_safety"])
        by = [g for g in ("n",) if g != x]
        markers = iter(("s", "D", "p", "h", "8") * 4)
        for values, seq in (lin.groupby(by, sort=True) if by else [((), lin)]):
            seq = seq.drop_duplicates([x, "linear_safety"]).sort_values(x)
            values = values if isinstance(values, tuple) else (values,)
            label = f"linear-discrete limit {_case_label(by, values)}".strip()
            plot_once(ax, seq[x], seq["linear_safety"], ":", label, marker=next(markers), mfc="none", ms=8,
                      color="0.35")
    if x == "n":
        ax.set_xticks(sorted(part["n"].unique()))
    ax.set_xlabel(x.replace("_", " "))
    ax.set_ylabel(f"limit of {info['quantity']}")


def stability_limits(limits: pd.DataFrame, meta: dict[tuple[str, str], dict[str, str]], path: Path,
                     title: str) -> bool:
    """Measured limits against each probe's own theory: one panel per (solver, scene) probe, the limit in
    the probe's quantity against its x axis (damping ratio, or n), the theory's limit per case and, where
    computed, the linear-discrete limit.  `meta` gives each probe's quantity, theory label and x axis."""
    keys = [k for k in sorted(meta) if not limits[(limits["solver"] == k[0]) & (limits["scene"] == k[1])].empty]
    if limits.empty or not keys:
        return False
    fig, axes = plt.subplots(len(keys), 1, figsize=(9.5, 3.6 * len(keys)), squeeze=False)
    for ax, key in zip(axes[:, 0], keys, strict=True):
        solver, scene = key
        _limit_panel(ax, limits[(limits["solver"] == solver) & (limits["scene"] == scene)], meta[key])
        ax.set_title(f"{solver} on {scene}", fontsize=8)
        ax.grid(True, alpha=0.3)
        legend_outside(ax)
    return _save(fig, path, title)


def stability_map(part: pd.DataFrame, path: Path, title: str) -> bool:
    """Status of each map run over (dt / dt_theory, damping ratio), one panel per drive amplitude."""
    if part.empty:
        return False
    amps = sorted(part["drive_amplitude"].unique())
    fig, axes = plt.subplots(1, len(amps), figsize=(3.0 * len(amps) + 1.5, 3.4), sharey=True, squeeze=False)
    for ax, D in zip(axes[0], amps, strict=True):
        sub = part[part["drive_amplitude"] == D]
        for status, (marker, colour) in STATUS_STYLE.items():
            pick = sub[sub["run_status"] == status]
            if not pick.empty:
                ax.scatter(pick["dt_ratio"], pick["damping_ratio"].clip(lower=1e-5), marker=marker, c=colour,
                           label=status)
        ax.axvline(1.0, color="k", lw=0.8)
        ax.set_yscale("log")
        ax.set_xlabel("dt / dt_theory")
        ax.set_title(f"D = {D:g} a", fontsize=8)
    axes[0][0].set_ylabel("damping ratio (0 drawn at 1e-5)")
    handles: dict[str, Any] = {}
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    if handles:
        axes[0][-1].legend(list(handles.values()), list(handles), fontsize=6, loc="upper left",
                           bbox_to_anchor=(1.04, 1.0), borderaxespad=0.0)
    return _save(fig, path, title)


def axis_value(result: dict[str, Any], name: str) -> float:
    """The value of a cell along a figure axis: n, refine, h, a solver or scene parameter, a summary scalar,
    or an error err.SET.NORM (nan when the cell has none)."""
    if name in ("n", "refine"):
        return float(result[name])
    if name == "h":
        return spacing(result)
    if name.startswith("err."):
        return stored_errors(result).get(name.removeprefix("err."), math.nan)
    for part in ("solver_params", "scene_params", "summary"):
        value = (result.get(part) or {}).get(name)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
    return math.nan


def parameter_figure(results: list[dict[str, Any]], path: Path, title: str, x: str, ys: list[str]) -> bool:
    """Each metric in `ys` against `x` (a swept parameter, n, refine or h), one panel per metric, one line per
    solver and setting of the other parameters that vary (n among them): an error against the horizon m at
    fixed h, a frequency against krot.  Log axes where every drawn value is positive."""
    ok = [r for r in results if r.get("status") == "ok" and math.isfinite(axis_value(r, x))]
    panels = [y for y in ys if any(math.isfinite(axis_value(r, y)) for r in ok)]
    if not panels:
        return False
    others = [k for k in _varying(ok) if k != x] + (["n"] if x != "n" and len({r["n"] for r in ok}) > 1 else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels) + 2.5, 4), squeeze=False)
    for ax, y in zip(axes[0], panels, strict=True):
        series: dict[str, list[tuple[float, float]]] = {}
        for r in ok:
            label = " ".join([r["solver"], *(f"{k}={r[k] if k == 'n' else (r.get('solver_params') or {}).get(k)}"
                                             for k in others)])
            series.setdefault(label, []).append((axis_value(r, x), axis_value(r, y)))
        values = [v for pts in series.values() for _, v in pts if math.isfinite(v)]
        for label, pts in series.items():
            pts = sorted(p for p in pts if math.isfinite(p[1]))
            if pts:
                plot_once(ax, [p[0] for p in pts], [abs(p[1]) for p in pts] if all(v > 0 for v in values) else
                          [p[1] for p in pts], "o-", label)
        positive_x = all(axis_value(r, x) > 0 for r in ok)
        if all(v > 0 for v in values):
            log_axes(ax, x, y, logx=positive_x)
        else:
            ax.set_xlabel(x)
            ax.set_ylabel(y)
            ax.grid(True, alpha=0.3)
            legend_outside(ax, 6.5)
    return _save(fig, path, title)



def history(results: list[dict[str, Any]], path: Path, title: str) -> bool:
    """Column 1 of each cell's diagnostics history against column 0 (time), over the reference curve of each scene
    drawn (`Reference.history`, where its spec has one); one panel per lattice n."""
    drawn = [r for r in results if len(((r.get("diagnostics") or {}).get("history") or {}).get("columns", [])) >= 2]
    if not drawn:
        return False
    ns = sorted({r["n"] for r in drawn})
    varying = _varying(drawn)
    fig, axes = plt.subplots(len(ns), 1, figsize=(10, 2.8 * len(ns)), squeeze=False)
    for ax, n in zip(axes[:, 0], ns, strict=True):
        for r in (r for r in drawn if r["n"] == n):
            columns = r["diagnostics"]["history"]["columns"]
            rows = np.asarray(r["diagnostics"]["history"]["rows"], float).reshape(-1, len(columns))
            label = _label(r, varying) + ("" if r["status"] == "ok" else f" ({r['status']})")
            plot_once(ax, rows[:, 0], rows[:, 1], "", label, lw=1)
            spec = get_spec(r["scene"])
            curve = spec.reference.history if spec.reference is not None else None
            t = np.linspace(0.0, float(rows[-1, 0]) if len(rows) else 0.0, 2000)
            found = None
            if curve is not None and len(rows):
                scene = spec.make(**r.get("scene_params", {}))
                found = curve(scene, t, r.get("summary") or {}) if _takes_summary(curve) else curve(scene, t)
            if found is not None:
                plot_once(ax, t, found[0], "", found[1], **CONTINUUM_STYLES[1])
        ax.set_title(f"n = {n}", fontsize=8)
        ax.set_xlabel(columns[0])
        ax.set_ylabel(columns[1])
        ax.grid(True, alpha=0.3)
        legend_outside(ax)
    return _save(fig, path, title)


def _takes_summary(curve: Callable[..., Any]) -> bool:
    """Whether a reference's history curve takes the cell's summary as a third argument (it may be drawn for
    the run's own lattice; a curve of two arguments is the scene's alone)."""
    try:
        inspect.signature(curve).bind(None, None, None)
    except (TypeError, ValueError):
        return False
    return True


GROUP_FIGURES = {"edge-profiles": edge_profiles, "render-3d": render_3d, "history": history}


def benchmark_history(runs: pd.DataFrame, path: Path) -> bool:
    """Mean time of every benchmark across the saved runs (the regression history)."""
    if runs.empty:
        return False
    fig, ax = plt.subplots(figsize=(10, 4))
    _lines(ax, runs.groupby("benchmark"), "run", "mean_s", along=False)
    ax.set_title("Benchmark history (tox -e bench)", fontsize=9)
    log_axes(ax, "saved run", "mean time [s]", logx=False, legend=5)
    return _save(fig, path)


def benchmark_scaling(runs: pd.DataFrame, path: Path) -> bool:
    """ns per pair-step against particle count in the latest run, per benchmark family."""
    need = {"ns_per_pair_step", "particles"}
    if runs.empty or not need <= set(runs.columns):
        return False
    last = runs[runs["run"] == runs["run"].max()].dropna(subset=list(need))
    if last.empty:
        return False
    fig, ax = plt.subplots(figsize=(8.5, 4))
    _lines(ax, last.groupby(last["benchmark"].str.split("[").str[0]), "particles", "ns_per_pair_step")
    ax.set_title("Particle kernels: cost per pair-step against N (latest benchmark run)", fontsize=9)
    log_axes(ax, "particles N", "ns per pair-step")
    return _save(fig, path)
