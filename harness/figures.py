"""Report figures (PNG and SVG): convergence, cost, work-precision, stability, edge profiles, 3-D renders,
benchmarks.

Each function takes tables or cached results and a path without suffix, and writes `path.png` and
`path.svg`; it returns True when it drew something.  Nothing here runs a solver.  `GROUP_FIGURES` is
the registry of the figures a study group can ask for by name (its `figures` list).
"""

from __future__ import annotations

import json
import textwrap
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

EDGES = ("front_top_edge", "bottom_back_edge")
CONTINUUM_STYLES = tuple(dict(lw=2.0, color=c, ls=ls, alpha=0.75)
                         for c, ls in (("k", "-"), ("0.45", "--"), ("0.25", ":"), ("0.6", "-.")))


def _wrap(title: str, width: int = 90) -> str:
    return "\n".join(textwrap.wrap(title, width))


def _save(fig: Any, path: Path) -> bool:
    title = fig.get_suptitle()
    lines = title.count("\n") + 1 if title else 0
    title_room = (0.17 * lines + 0.08) / fig.get_figheight() if lines else 0.0  # inches kept for the title
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 1.0 - title_room))
    fig.savefig(path.with_suffix(".png"), dpi=110)
    fig.savefig(path.with_suffix(".svg"))
    plt.close(fig)
    return True


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
    """log-log error (or value) against h, one line per solver sequence and column, with the fitted order."""
    orders = {}
    if fits is not None and not fits.empty and "order" in fits:
        orders = {(r.solver, r.params, r.quantity): r.order for r in fits.itertuples() if pd.notna(r.order)}
    fig, ax = plt.subplots(figsize=(6, 4))
    for (solver, params), seq in levels.groupby(["solver", "params"], sort=False):
        seq = seq.sort_values("h")
        for col in columns:
            y = pd.to_numeric(seq[col], errors="coerce").abs()
            if len(y) and (y > 0).all():
                order = orders.get((solver, params, col))
                slope = f" (fitted order {order:.2f})" if order is not None else ""
                ax.loglog(seq["h"], y, "o-", label=f"{solver} {params} {col}{slope}".strip())
    ax.set_xlabel("h [m]")
    errors = any(c.endswith(("l2", "linf")) or c.startswith("err.") for c in columns)
    ax.set_ylabel("error (relative for err.*)" if errors else "|value|")
    ax.set_title(_wrap(title, 80), fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    if ax.lines:
        ax.legend(fontsize=6)
    return _save(fig, path)


def cost(df: pd.DataFrame, path: Path, title: str) -> bool:
    """Wall time against unknowns per solver."""
    fig, ax = plt.subplots(figsize=(6, 4))
    for solver, seq in df.groupby("solver"):
        ax.loglog(seq["unknowns"], seq["wall_s"], "o-", label=solver)
    ax.set_xlabel("unknowns")
    ax.set_ylabel("wall time [s]")
    ax.set_title(_wrap(title, 80), fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return _save(fig, path)


def work_precision(df: pd.DataFrame, error: str, path: Path, title: str) -> bool:
    """Error against wall time (left) and against the work counter (right), one line per solver."""
    if df.empty:
        return False
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4))
    for solver, seq in df.groupby("solver"):
        seq = seq.sort_values("wall_s")
        left.loglog(seq["wall_s"], seq[error], "o-", label=solver)
        seq = seq.sort_values("work")
        right.loglog(seq["work"], seq[error], "o-", label=f"{solver} ({seq['work_kind'].iloc[0]})")
    left.set_xlabel("wall time [s]")
    right.set_xlabel("work (pair-steps or unknowns x time steps)")
    for ax in (left, right):
        ax.set_ylabel(error)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


PHASE_MARKERS = {"design": "o", "local": "s", "replica": "^", "sensitivity": "D"}


def calibration_trace(trace: pd.DataFrame, path: Path, title: str) -> bool:
    """Objective against evaluation (log scale), by phase, the best so far as a line; failed sets as x at the
    top (they have no objective)."""
    if trace.empty:
        return False
    fig, ax = plt.subplots(figsize=(8, 4))
    ok = trace[trace["status"] == "ok"]
    for phase, part in ok.groupby("phase", sort=False):
        ax.semilogy(part["evaluation"], part["objective"], PHASE_MARKERS.get(phase, "o"), ms=5, label=phase,
                    alpha=0.8)
    if "best_so_far" in trace and trace["best_so_far"].notna().any():
        ax.semilogy(trace["evaluation"], trace["best_so_far"], "k-", lw=1, label="best so far (search)")
    bad = trace[trace["status"] != "ok"]
    if not bad.empty:
        top = ok["objective"].max() if not ok.empty else 1.0
        ax.semilogy(bad["evaluation"], np.full(len(bad), top * 1.5), "rx", label="failed set (" + ", ".join(
            sorted(bad["status"].unique())) + ")")
    ax.set_xlabel("evaluation")
    ax.set_ylabel("objective (calibrated on)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.suptitle(_wrap(title, 110), fontsize=9)
    return _save(fig, path)


def calibration_work_precision(trace: pd.DataFrame, path: Path, title: str) -> bool:
    """Objective against the wall time and the work counter of each evaluated parameter set (ok ones)."""
    ok = trace[trace["status"] == "ok"] if not trace.empty else trace
    if ok.empty:
        return False
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 4))
    for phase, part in ok.groupby("phase", sort=False):
        marker = PHASE_MARKERS.get(phase, "o")
        left.loglog(part["wall_s"], part["objective"], marker, label=phase, alpha=0.8)
        right.loglog(part["work"], part["objective"], marker, label=phase, alpha=0.8)
    left.set_xlabel("wall time of the set's cells [s]")
    right.set_xlabel(f"work ({ok['work_kind'].iloc[0]})")
    for ax in (left, right):
        ax.set_ylabel("objective (calibrated on)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


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
    ax.legend(fontsize=7)
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


def edge_profiles(results: list[dict[str, Any]], path: Path, title: str) -> bool:
    """The paper's Fig. 9: relative value along the two edges, particle polylines against continuum curves.

    One row of panels per lattice n; one line per parameter set (e.g. per damping value).
    """
    ok = [r for r in results if all(_shown(r, e) for e in EDGES)]
    if not ok:
        return False
    ns = sorted({r["n"] for r in ok})
    varying = _varying(ok)
    fig, axes = plt.subplots(len(ns), 2, figsize=(9, 2.8 * len(ns)), squeeze=False)
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
                ax.plot(pts[:, 2] * 1e3, vals, label=label, **style)
            ax.set_title(f"n = {n}: {edge.replace('_', ' ')}", fontsize=8)
            ax.set_xlabel("z [mm]")
            ax.set_ylabel("relative value")
            ax.grid(True, alpha=0.3)
        axes[row, 1].legend(fontsize=6, loc="best")
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


def render_3d(results: list[dict[str, Any]], path: Path, title: str) -> bool:
    """Particles coloured by their relative value (the paper's Figs. 2-4), one panel per n."""
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
        fig.colorbar(sc, ax=ax, shrink=0.6, label="relative hotness")
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


STATUS_STYLE = {"ok": ("o", "tab:green"), "unstable": ("x", "tab:red"), "defect": ("s", "tab:orange"),
                "non-stationary": ("^", "tab:blue")}


def stability_limits(limits: pd.DataFrame, meta: dict[tuple[str, str], dict[str, str]], path: Path,
                     title: str) -> bool:
    """Measured limits against each probe's own theory: one panel per (solver, scene) probe, the limit in the
    probe's quantity against its x axis (damping ratio, or n), the theory's limit per case and, where
    computed, the linear-discrete limit.  `meta` gives each probe's quantity, theory label and x axis."""
    if limits.empty:
        return False
    keys = sorted(meta)
    fig, axes = plt.subplots(1, len(keys), figsize=(5.2 * len(keys), 3.8), squeeze=False)
    for ax, key in zip(axes[0], keys, strict=True):
        solver, scene = key
        info = meta[key]
        part = limits[(limits["solver"] == solver) & (limits["scene"] == scene)]
        x = info["x_axis"]
        theory = part[[x, "safety_theory"]].drop_duplicates().sort_values(x)
        ax.plot(theory[x], theory["safety_theory"], "k-", lw=1.5, label=info["theory_label"])
        groups = ["n", "drive_amplitude"] if x != "n" else ["drive_amplitude"]
        for values, seq in part.groupby(groups, dropna=False):
            values = values if isinstance(values, tuple) else (values,)
            label = " ".join(f"{g}={v:g}" if isinstance(v, float) else f"{g}={v}" for g, v in zip(groups, values,
                             strict=True) if not (isinstance(v, float) and np.isnan(v)))
            seq = seq.sort_values(x)
            ax.plot(seq[x], seq["measured_safety"], "o--", label=f"measured {label}".strip())
        if "linear_safety" in part and part["linear_safety"].notna().any():
            lin = part.dropna(subset=["linear_safety"]).drop_duplicates([x, "n", "linear_safety"]).sort_values(x)
            ax.plot(lin[x], lin["linear_safety"], ":", color="grey", marker=".", label="linear-discrete limit")
        ax.set_xlabel(x.replace("_", " "))
        ax.set_ylabel(f"limit of {info['quantity']}")
        ax.set_title(f"{solver} on {scene}", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=6)
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


def stability_map(part: pd.DataFrame, path: Path, title: str) -> bool:
    """Status of each map run over (dt / dt_theory, damping ratio), one panel per drive amplitude."""
    if part.empty:
        return False
    amps = sorted(part["drive_amplitude"].unique())
    fig, axes = plt.subplots(1, len(amps), figsize=(3.2 * len(amps), 3.4), sharey=True, squeeze=False)
    for ax, D in zip(axes[0], amps, strict=True):
        sub = part[part["drive_amplitude"] == D]
        for status, (marker, colour) in STATUS_STYLE.items():
            pick = sub[sub["status"] == status]
            ax.scatter(pick["dt_ratio"], pick["damping_ratio"].clip(lower=1e-5), marker=marker, c=colour,
                       label=status)
        ax.axvline(1.0, color="k", lw=0.8)
        ax.set_yscale("log")
        ax.set_xlabel("dt / dt_theory")
        ax.set_title(f"D = {D:g} a", fontsize=8)
    axes[0][0].set_ylabel("damping ratio (0 drawn at 1e-5)")
    axes[0][-1].legend(fontsize=6)
    fig.suptitle(_wrap(title, 120), fontsize=9)
    return _save(fig, path)


GROUP_FIGURES = {"edge-profiles": edge_profiles, "render-3d": render_3d}


def benchmark_runs(storage: Path) -> pd.DataFrame:
    """One row per (saved pytest-benchmark run, benchmark): mean/min seconds and extra_info."""
    rows = []
    for k, file in enumerate(sorted(storage.glob("*/*.json"))):
        try:
            doc = json.loads(file.read_text())
        except (OSError, json.JSONDecodeError):
            continue
        commit = (doc.get("commit_info") or {}).get("id", "")[:10]
        for b in doc.get("benchmarks", []):
            extra = {k2: v for k2, v in (b.get("extra_info") or {}).items() if isinstance(v, (int, float, str))}
            rows.append({"run": k, "saved": file.stem, "datetime": doc.get("datetime", ""), "commit": commit,
                         "benchmark": b.get("name", ""), "mean_s": b["stats"]["mean"], "min_s": b["stats"]["min"],
                         **extra})
    return pd.DataFrame(rows)


def benchmark_history(runs: pd.DataFrame, path: Path) -> bool:
    """Mean time of every benchmark across the saved runs (the regression history)."""
    if runs.empty:
        return False
    fig, ax = plt.subplots(figsize=(7, 4))
    for name, seq in runs.groupby("benchmark"):
        ax.semilogy(seq["run"], seq["mean_s"], "o-", label=name)
    ax.set_xlabel("saved run")
    ax.set_ylabel("mean time [s]")
    ax.set_title("Benchmark history (tox -e bench)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=5, ncol=2)
    return _save(fig, path)


def benchmark_scaling(runs: pd.DataFrame, path: Path) -> bool:
    """ns per pair-step against particle count in the latest run, per benchmark family."""
    need = {"ns_per_pair_step", "particles"}
    if runs.empty or not need <= set(runs.columns):
        return False
    last = runs[runs["run"] == runs["run"].max()].dropna(subset=list(need))
    if last.empty:
        return False
    fig, ax = plt.subplots(figsize=(6, 4))
    for family, seq in last.groupby(last["benchmark"].str.split("[").str[0]):
        seq = seq.sort_values("particles")
        ax.loglog(seq["particles"], seq["ns_per_pair_step"], "o-", label=family)
    ax.set_xlabel("particles N")
    ax.set_ylabel("ns per pair-step")
    ax.set_title("Particle kernels: cost per pair-step against N (latest benchmark run)", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)
    return _save(fig, path)
