"""Rows of the ns-per-pair-step-against-N plot from a saved run of the scaling benchmarks (a test helper)."""

from __future__ import annotations

import json
from pathlib import Path


def rows_from_benchmark_json(path: str | Path) -> list[dict]:
    """Rows {N, ns_per_pair_step, bytes_per_particle, threads, force_pass, name} of the scaling benchmarks
    in a pytest-benchmark JSON file (benchmarks whose extra_info has those keys), sorted by N."""
    data = json.loads(Path(path).read_text())
    rows = []
    for b in data.get("benchmarks", []):
        info = b.get("extra_info", {})
        if "ns_per_pair_step" in info and "bytes_per_particle" in info and "particles" in info:
            rows.append({"N": int(info["particles"]), "ns_per_pair_step": float(info["ns_per_pair_step"]),
                         "bytes_per_particle": float(info["bytes_per_particle"]),
                         "threads": int(info.get("threads", 0)), "force_pass": info.get("force_pass", ""),
                         "name": b.get("name", "")})
    return sorted(rows, key=lambda r: (r["N"], r["force_pass"], r["threads"]))
