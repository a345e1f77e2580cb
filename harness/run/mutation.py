"""Mutation testing of a study's claims: each mutant runs the study in a process of its own, and a claim that
passes on the original code and not on a mutant has caught it.

A mutant's process (`overlay`) sees the mutated module as an edited copy in the mutant's folder,
`<cache>/mutants/<study>/<name>-<identity>/`.  Nothing of a mutant reaches the real caches: its numba cache is a
copy (the numba guard recompiles exactly the kernels whose closure holds the mutated module), and its result
cache is its own folder, seeded from the baseline only where a cell key covers every code the mutant can change
(`Mutant.seedable`); named by the hash of its definition and source, it lets an interrupted run resume.

Outcomes: `killed` (a claim that passed on the baseline does not pass), `survived`, `invalid` (the edit is not
valid Python, changes no code, or its module or a kernel it changes does not import or compile; never counted
as killed) and `crashed` (its study did not end with verdicts: a crash is not a claim catching the defect).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import hashlib
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pcverify.harness.judge.verdict import STATES
from pcverify.harness.run import overlay
from pcverify.harness.run.cache import Cache
from pcverify.harness.run.execution import identify
from pcverify.harness.run.files import read_json
from pcverify.harness.run.progress import progress_bar
from pcverify.harness.run.workers import exit_description
from pcverify.harness.study.mutants import Mutant
from pcverify.harness.study.study import Study

OUTCOMES = ("killed", "survived", "invalid", "crashed")
STOP_GRACE_S = 10.0  # after SIGTERM, a mutant's process has this long to stop cleanly before SIGKILL
COMPILE_ERRORS = re.compile(r"(TypingError|LoweringError|UnsupportedError|NumbaError|SyntaxError|IndentationError|"
                            r"ImportError|ModuleNotFoundError)\b")
BOOT = ("import importlib.util as u, sys; s = u.spec_from_file_location('pcverify_overlay', sys.argv[1]); "
        "m = u.module_from_spec(s); s.loader.exec_module(m); sys.exit(m.main(sys.argv[2:]))")


@dataclass(frozen=True)
class Prepared:
    """A mutant ready to run: its original and edited source and its folder."""

    mutant: Mutant
    original: Path
    edited: str
    folder: Path
    changes_code: bool
    syntax_error: str


def prepare(mutant: Mutant, cache_root: Path, study: str) -> Prepared:
    """Resolve and apply a mutant's edit (MutantError, one line, when it does not apply as declared)."""
    source, edited = mutant.edited()
    try:
        compile(edited, str(mutant.path()), "exec")
        syntax = ""
    except (SyntaxError, ValueError) as exc:
        syntax = f"{type(exc).__name__}: {' '.join(str(exc).split())}"
    folder = cache_root / "mutants" / study / f"{mutant.name}-{mutant.identity(edited)}"
    return Prepared(mutant, mutant.path(), edited, folder, mutant.changes_code(source, edited), syntax)


def judge(baseline: list[dict[str, Any]], mutated: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """Per claim of the baseline its state there and on the mutant (the worst of its verdicts: fail,
    inconclusive, not-applicable, pass; "missing" when the mutant's report has none), how many of its cases pass
    on the baseline, `caught`: those cases that do not pass on the mutant (a claim judged per n, say, catches
    a defect with each case that passed), and `incidental`: the caught cases the claim did not measure on the
    mutant (no value: its cells ran out of steps, stopped, failed or were skipped, or the case is missing)."""
    def cases(records: list[dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
        return {(r["claim"], str(r.get("case") or "")): r for r in records}

    def worst(verdicts: list[str]) -> str:
        return next((s for s in STATES if s in verdicts), "missing")

    before, after = cases(baseline), cases(mutated)
    out: dict[str, dict[str, Any]] = {}
    for claim in dict.fromkeys(c for c, _ in before):
        mine = [(case, r["verdict"]) for (c, case), r in before.items() if c == claim]
        passed = [case for case, v in mine if v == "pass"]
        caught = [case for case in passed if after.get((claim, case), {}).get("verdict", "missing") != "pass"]
        out[claim] = {"baseline": worst([v for _, v in mine]),
                      "mutant": worst([r["verdict"] for (c, _), r in after.items() if c == claim]),
                      "passing": len(passed), "caught": caught,
                      "incidental": [case for case in caught if not _measured(after.get((claim, case)))]}
    return out


def _measured(record: dict[str, Any] | None) -> bool:
    """Whether a verdict record judged a number (not a case left unjudged by its cells' status or rows)."""
    value = (record or {}).get("value")
    return isinstance(value, (int, float)) and math.isfinite(value)


def measured_catches(claim: dict[str, Any]) -> list[str]:
    """The cases in which a claim (as `judge` gives it) caught a mutant with a number it measured."""
    return [case for case in claim.get("caught", []) if case not in claim.get("incidental", [])]


def kill_kind(claims: dict[str, dict[str, Any]], expect: Iterable[str]) -> str:
    """How a killed mutant was caught: "expected" (a claim it declares in `expect` measured it), "measuring"
    (another claim's number moved beyond its bound), "incidental" (only cases no claim measured: a step budget,
    a stationarity stop, a failed check), "" when nothing caught it."""
    measuring = [c for c, s in claims.items() if measured_catches(s)]
    if not measuring:
        return "incidental" if caught_by(claims) else ""
    return "expected" if set(measuring) & set(expect) else "measuring"


def caught_by(claims: dict[str, dict[str, Any]]) -> list[str]:
    """The claims with a case that passed on the baseline and does not pass on the mutant."""
    return [c for c, s in claims.items() if s.get("caught")]


def _copy_data_files(package: Path, target: Path) -> None:
    """The files beside the mutated module that are not Python (a solver's model notes, say) copied beside its
    edited copy: a module that finds them next to its own `__file__` finds them in the mutant too."""
    for path in package.iterdir():
        if path.is_file() and path.suffix not in (".py", ".pyc"):
            shutil.copy2(path, target / path.name)  # each run: a copy kept from an earlier run may be stale


def _copy_numba_cache(target: Path, packages: Iterable[Path]) -> None:
    """A copy of the real numba cache for a mutant: NUMBA_CACHE_DIR's folder, or, without it, the in-tree
    `__pycache__` entries of the packages' folders laid out as numba lays out a cache folder."""
    if target.exists():
        return
    real = os.environ.get("NUMBA_CACHE_DIR")
    ignore = shutil.ignore_patterns("*.tmp.*", "*.lock")
    if real and Path(real).is_dir():
        with contextlib.suppress(shutil.Error):  # an entry replaced while copied: that kernel compiles again
            shutil.copytree(real, target, ignore=ignore, dirs_exist_ok=True)
        return
    target.mkdir(parents=True)
    for root in packages:
        for pycache in root.rglob("__pycache__"):
            entries = [p for p in pycache.iterdir() if p.suffix in (".nbi", ".nbc")]
            if entries:
                source_dir = str(pycache.parent.resolve())
                sub = target / f"{pycache.parent.name}_{hashlib.sha1(source_dir.encode()).hexdigest()}"
                sub.mkdir(exist_ok=True)
                for p in entries:
                    shutil.copyfile(p, sub / p.name)


def _seed(results: Path, cache: Cache, keys: Iterable[str]) -> int:
    """Copy the baseline's entries of `keys` that the mutant's result cache lacks (copies: a write there can
    never reach the real cache); returns how many."""
    results.mkdir(parents=True, exist_ok=True)
    copied = 0
    for key in keys:
        real, mine = cache.path(key), results / f"{key}.json"
        if real.is_file() and not mine.exists():
            shutil.copyfile(real, mine)
            copied += 1
    return copied


def prune(folder: Path) -> None:
    """Remove the folders of earlier definitions or sources of the same mutant (same name, another hash)."""
    name = folder.name.rsplit("-", 1)[0]
    for old in folder.parent.glob(f"{name}-*"):
        stem, _, digest = old.name.rpartition("-")
        if old != folder and old.is_dir() and stem == name and re.fullmatch(r"[0-9a-f]{12}", digest):
            shutil.rmtree(old, ignore_errors=True)


class Runner:
    """Runs prepared mutants of one study, `jobs` at a time, each in its own process (killed with the run)."""

    def __init__(self, study: Study, baseline: list[dict[str, Any]], cache: Cache, time_limit: float,
                 mutant_time_limit: float, allow_large: bool = False) -> None:
        self.study, self.baseline, self.cache = study, baseline, cache
        self.time_limit, self.mutant_time_limit, self.allow_large = time_limit, mutant_time_limit, allow_large
        self.keys = frozenset(identify(c).key for g in study.groups for c in g.cells)
        self.live: set[subprocess.Popen] = set()
        self.lock = threading.Lock()
        self.stopping = threading.Event()

    def run(self, prepared: list[Prepared], jobs: int, progress: bool) -> list[dict[str, Any]]:
        """Every mutant's outcome, in the order given."""
        bar = progress_bar(len(prepared), f"{self.study.name}: mutants", "mutant", enabled=progress)
        done: dict[int, dict[str, Any]] = {}
        pool = concurrent.futures.ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="pcverify-mutant")
        try:
            futures = {pool.submit(self.one, p): i for i, p in enumerate(prepared)}
            for fut in concurrent.futures.as_completed(futures):
                done[futures[fut]] = out = fut.result()
                counts = {s: sum(o["status"] == s for o in done.values()) for s in OUTCOMES}
                bar.set_postfix(counts)
                bar.set_description(f"{self.study.name}: {out['name']} {out['status']}"[:70])
                bar.update(1)
        except BaseException:
            self.stop()
            raise
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
            bar.close()
        return [done[i] for i in range(len(prepared))]

    def stop(self) -> None:
        """Stop every mutant's process (and keep new ones from starting)."""
        self.stopping.set()
        with self.lock:
            live = list(self.live)
        for proc in live:
            with contextlib.suppress(OSError):
                os.killpg(proc.pid, signal.SIGTERM)
        deadline = time.monotonic() + STOP_GRACE_S
        for proc in live:
            _stop(proc, max(0.0, deadline - time.monotonic()))

    def one(self, p: Prepared) -> dict[str, Any]:
        """Run one mutant and say what came of it."""
        m = p.mutant
        base = {"name": m.name, "package": m.package, "file": m.file, "module": m.module(), "breaks": m.breaks,
                "expect": list(m.expect), "origin": m.origin, "folder": str(p.folder)}
        t0 = time.perf_counter()
        if p.syntax_error:
            return base | self._outcome("invalid", f"the edited module is not valid Python ({p.syntax_error})", t0)
        if not p.changes_code:
            return base | self._outcome("invalid", "the edit changes no code (only comments, layout or docstrings): "
                                        "an equivalent mutant", t0)
        if self.stopping.is_set():
            return base | self._outcome("crashed", "not run: the run was interrupted", t0)
        p.folder.mkdir(parents=True, exist_ok=True)
        prune(p.folder)
        source = p.folder / "source" / p.original.name
        source.parent.mkdir(exist_ok=True)
        if not source.is_file() or source.read_text(encoding="utf-8") != p.edited:
            source.write_text(p.edited, encoding="utf-8")  # rewritten only when it changed: numba keys on it
        _copy_data_files(p.original.parent, source.parent)
        results = p.folder / "results"
        seeded = _seed(results, self.cache, sorted(self.keys)) if m.seedable() else 0
        results.mkdir(exist_ok=True)
        roots = {p.original.parent, *(Path(s.origin).parent for s in _pcverify_specs())}
        _copy_numba_cache(p.folder / "numba", roots)
        outcome_file = p.folder / "outcome.json"
        common = [str(self.study.path), "--out", str(p.folder / "report"), "--cache", str(results), "--json",
                  "--time-limit", f"{self.time_limit:g}"] + (["--allow-large"] if self.allow_large else [])
        common += [arg for gid in self.study.selected for arg in ("--group", gid)]
        code, timed_out = overlaid(m.module(), source, p.original, [["study", *common, "--dry-run"],
                                                                    ["study", *common, "--jobs", "1"]],
                                   p.folder, self.mutant_time_limit, self.live, self.lock)
        doc, _ = read_json(outcome_file)
        out = base | self._classify(doc if isinstance(doc, dict) else {}, code, timed_out, p.folder, Cache(results), t0,
                                    m.expect)
        out["seeded"] = seeded
        if out["status"] != "crashed":
            shutil.rmtree(p.folder / "numba", ignore_errors=True)  # 18 MB each; a crashed run keeps it to resume
        return out

    def _outcome(self, status: str, reason: str, t0: float, **extra: Any) -> dict[str, Any]:
        return {"status": status, "reason": reason, "caught_by": [], "claims": {}, "cells": {},
                "cells_changed": 0, "recomputed": 0, "seeded": 0, "wall_s": round(time.perf_counter() - t0, 3)} | extra

    def _classify(self, doc: dict[str, Any], code: int | None, timed_out: bool, folder: Path, results: Cache,
                  t0: float, expect: Iterable[str] = ()) -> dict[str, Any]:
        if "invalid" in doc:
            return self._outcome("invalid", str(doc["invalid"]), t0)
        ran = doc.get("results") or []  # the dry run (each cell's key), then the study (cells, verdicts)
        plan, summary = (r.get("json") for r in (ran + [{}, {}])[:2])
        if timed_out or len(ran) < 2 or ran[1].get("exit") != 0 or not isinstance(summary, list) or not summary:
            why = (f"exceeded the mutant time limit of {self.mutant_time_limit:g} s (finished cells are kept: a rerun "
                   "resumes)" if timed_out else f"its study ended without verdicts ({exit_description(code)}): "
                   f"{_last_line(folder / 'run.log')}")
            return self._outcome("crashed", why, t0)
        counts = {k: summary[0].get(k, 0) for k in ("cells", "cached", "done", "failed")}
        changed = [r["key"] for r in (plan or [{}])[0].get("cells", []) if r.get("key") not in self.keys]
        entries = [(results.load(k)[0] or {}) for k in changed]
        claims = judge(self.baseline, summary[0].get("verdicts") or [])
        extra = {"claims": claims, "cells": counts, "cells_changed": len(changed), "recomputed": counts["done"]}
        broken = [str(r.get("reason") or "") for r in entries
                  if r.get("status") == "failed" and COMPILE_ERRORS.match(str(r.get("reason") or ""))]
        if broken:
            return self._outcome("invalid", f"its code does not compile or import: {len(broken)} of the {len(changed)} "
                                 f"cells whose key it changed failed so, e.g. {broken[0][:300]}", t0, **extra)
        caught = caught_by(claims)
        if caught:
            kind = kill_kind(claims, expect)
            why = ("caught only where no claim measured it: " + "; ".join(
                f"{c} ({', '.join(claims[c]['incidental'])})" for c in caught) if kind == "incidental" else "")
            return self._outcome("killed", why, t0, **extra | {"caught_by": caught, "kill": kind})
        passing = [c for c, s in claims.items() if s.get("passing")]
        why = (f"every case that passes on the original passes on it ({len(passing)} claims)" if passing else
               "no claim passes on the original in any case: none can catch it")
        return self._outcome("survived", why, t0, **extra)


def overlaid(module: str, source: Path, original: Path, commands: list[list[str]], folder: Path,
             time_limit: float, live: set[subprocess.Popen] | None = None, lock: threading.Lock | None = None
             ) -> tuple[int | None, bool]:
    """Run pcverify `commands` in one process of their own in which `module` is loaded from `source` (`overlay`),
    with `folder`/numba as its numba cache; its output goes to `folder`/run.log, its outcome (`overlay.main`) to
    `folder`/outcome.json.  The process has a session of its own (stopped as a group) and is registered in `live`
    while it runs.  (exit code, whether it ran past `time_limit` seconds and was stopped)."""
    job = {"module": module, "source": str(source), "original": str(original), "sys_path": sys.path,
           "parent": os.getpid(), "outcome": str(folder / "outcome.json"), "commands": commands}
    (folder / "job.json").write_text(json.dumps(job, indent=1), encoding="utf-8")
    (folder / "outcome.json").unlink(missing_ok=True)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(folder / "numba"))
    live = set() if live is None else live
    lock = threading.Lock() if lock is None else lock
    with open(folder / "run.log", "wb") as log:
        proc = subprocess.Popen([sys.executable, "-c", BOOT, overlay.__file__, str(folder / "job.json")],
                                stdin=subprocess.DEVNULL, stdout=log, stderr=log, env=env, start_new_session=True)
        with lock:
            live.add(proc)
        try:
            proc.wait(time_limit)
            return proc.returncode, False
        except subprocess.TimeoutExpired:
            _stop(proc)
            return proc.returncode, True
        finally:
            with lock:
                live.discard(proc)


def _stop(proc: subprocess.Popen, grace: float = STOP_GRACE_S) -> None:
    """SIGTERM to the process's group (its study stops cleanly, its workers with it), SIGKILL after `grace`."""
    with contextlib.suppress(OSError):
        os.killpg(proc.pid, signal.SIGTERM)
    try:
        proc.wait(grace)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(OSError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def _last_line(log: Path) -> str:
    """The last non-empty line a mutant's process wrote (its error line or the end of a traceback)."""
    try:
        lines = [line.strip() for line in log.read_text(errors="replace").splitlines() if line.strip()]
    except OSError:
        return "no output"
    return (lines[-1] if lines else "no output")[:300]


def _pcverify_specs() -> list[Any]:
    """The specs of pcverify's top-level packages (their folders hold in-tree numba caches)."""
    names = ("pcverify", "pcverify.harness", "pcverify.solvers", "pcverify.references")
    return [sys.modules[n].__spec__ for n in names if n in sys.modules and sys.modules[n].__spec__ is not None
            and sys.modules[n].__spec__.origin]
