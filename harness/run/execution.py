"""Running a study's cells: one path for every cell, the cache in front of it, local or Dask workers.

A cell is identified by a content hash (`cell_identity`); a cached result is read back, not recomputed.  A
computed cell runs in a worker process (`workers`) that is killed past the cell's time limit, one per --jobs,
or on a Dask cluster; each finished cell is stored at once, so an interrupted study loses nothing.  Timed
cells run last, one at a time in one worker, after a warm-up solve per solver there.  A cell's identity comes
from the cell, never from what the solver returns, and each solve gets its own copy of the scene.
"""

from __future__ import annotations

import contextlib
import contextvars
import copy
import datetime
import logging
import math
import os
import platform
import re
import sys
import threading
import time
import uuid
from collections import Counter
from collections.abc import Iterator
from typing import Any, NamedTuple

from threadpoolctl import threadpool_limits
from tqdm import tqdm

from pcverify.fingerprint import code_fingerprint, module_fingerprint
from pcverify.harness.judge import compare
from pcverify.harness.run.cache import CLAIMED, HELD, Cache, cell_key
from pcverify.harness.run.dependencies import dependencies, recording
from pcverify.harness.run.interrupt import check_interrupted, ignore_sigint_in_worker
from pcverify.harness.run.limits import DEFAULT_TIME_LIMIT, EstimateError, check_work
from pcverify.harness.run.progress import progress_bar
from pcverify.harness.run.workers import Outcome, describe_exception, pool
from pcverify.harness.study.boundary import Inadmissible
from pcverify.harness.study.plugins import load_plugins
from pcverify.harness.study.study import Cell, Study
from pcverify.harness.study.tasks import SolveTask, SupportsAnswerError, ask_supports
from pcverify.scene import Resolution, Scene, SceneError, shown
from pcverify.solvers.registry import SolverUnavailable, get_solver, named, snapshot

try:  # optional dependency: pip install 'pcverify[dask]'
    from distributed import Client, as_completed
except ImportError:  # --scheduler then says how to install it
    Client = as_completed = None

SCHEDULER_ADDRESS = re.compile(r"^(tcp|tls|ws|wss|ucx)://[A-Za-z0-9._\-\[\]:]+:[0-9]{1,5}$|^inproc://[\w./\-]+$")


_TIME_LIMIT: contextvars.ContextVar[float] = contextvars.ContextVar("pcverify_time_limit", default=DEFAULT_TIME_LIMIT)
_SOLVED_HERE: set[str] = set()  # solvers this process has solved with: a first solve pays imports and compilation
REPEAT_BELOW_S = 0.5  # a timed cell is solved again only while one solve takes less CPU time than this
_SCENE_ERROR = "pcverify-scene-error"  # a worker's reply that is a SceneError for the command line to report


@contextlib.contextmanager
def cell_time_limit(seconds: float | None) -> Iterator[None]:
    """Within the block, a computed cell is killed after `seconds` (None: DEFAULT_TIME_LIMIT): for every
    `execute` and `run_cell` that is not given its own limit, e.g. those a calibration starts."""
    token = _TIME_LIMIT.set(DEFAULT_TIME_LIMIT if seconds is None else float(seconds))
    try:
        yield
    finally:
        _TIME_LIMIT.reset(token)


def cell_identity(cell: Cell) -> tuple[dict[str, Any], str | None]:
    """(key payload, reason the cell will not be solved or None) of a cell.  The payload holds the scene's
    content hash, the solver's name and code fingerprint (and the task's), the resolution, the task, the
    parameters and the compare step's fingerprint.  A cell is not solved when it is skipped, or when the
    solver's `supports` or parameter check raised; a SceneError of the parameter check propagates."""
    payload: dict[str, Any] = {"scene": cell.scene.content_hash(), "solver": cell.solver, "n": cell.n,
                               "refine": cell.refine, "task": cell.task.name}
    if cell.serial:
        payload["timing"] = "serial-after-warm-up" + (f", least of {cell.repeats}" if cell.repeats > 1 else "")
        payload["timed_by"] = cell.timed_by  # two studies' timed passes never share a timing
    if cell.expressions:  # the same value from another expression is another cell of the tables
        payload["expressions"] = dict(cell.expressions)
    try:
        load_plugins(cell.plugins, cell.plugin_folder)
        solver = get_solver(cell.solver)
    except SolverUnavailable as exc:
        return payload | {"unavailable": True, "params": dict(cell.solver_params)}, str(exc)
    ok, reason, broken = _supported(cell, named(solver, cell.solver), copy.deepcopy(cell.scene))
    if broken:
        return payload | {"params": dict(cell.solver_params), "broken": True}, broken
    if not ok:  # skipped with the reason; its parameters may not even be the solver's
        return payload | {"params": dict(cell.solver_params), "skipped": True}, reason
    try:
        params = cell.task.check(named(solver, cell.solver), dict(cell.solver_params))
    except (SceneError, KeyboardInterrupt):
        raise
    except BaseException as exc:  # noqa: BLE001 - a plugin's own parameter check: its cell fails, never a traceback
        return payload | {"params": dict(cell.solver_params), "broken": True}, _checks_raised(cell, exc)
    return payload | {"params": params, "code": code_fingerprint(solver),
                      "task_code": module_fingerprint(type(cell.task).__module__),
                      "compare": compare.fingerprint(cell.scene)}, None


def untimed_key(cell: Cell) -> str:
    """The cache key `cell` would have outside a timed group: a cell of another group with this key computes
    the same solution, so it takes the timed cell's result instead of being solved twice."""
    payload = {k: v for k, v in cell_identity(cell)[0].items() if k not in ("timing", "timed_by")}
    return cell_key(payload)


class CellId(NamedTuple):
    """A cell's cache key (`cache.cell_key` of its `cell_identity` payload) and the reason it will not be
    solved (None: it will be)."""

    key: str
    skip: str | None


def identify(cell: Cell) -> CellId:
    """The cache key and skip reason of `cell`: the one place a cell's key is made."""
    payload, skip = cell_identity(cell)
    return CellId(cell_key(payload), skip)


def _supported(cell: Cell, solver: Any, scene: Scene) -> tuple[bool, str, str | None]:
    """(supported, reason, why the check itself failed or None): a `supports` that raises or answers
    something other than (True or False, text) fails the cell."""
    try:
        ok, reason = ask_supports(cell.task, solver, scene)
    except KeyboardInterrupt:
        raise
    except SupportsAnswerError as bad:
        return False, "", (f"solver {cell.solver!r}: supports(scene) returned {shown(bad.answer)}; allowed: (True or "
                           "False, a reason text)")
    except BaseException as exc:  # noqa: BLE001 - whatever a plugin's supports raises is its cell's failure
        return False, "", f"solver {cell.solver!r}: supports(scene) raised {describe_exception(exc)}"
    return ok, reason, None


def _checks_raised(cell: Cell, exc: BaseException) -> str:
    return f"solver {cell.solver!r}: checking its parameters raised {describe_exception(exc)}"


def _base(cell: Cell) -> dict[str, Any]:
    """The identity fields of a cell's result: the cell's, whatever the solver says of itself."""
    base = {"group": cell.group, "scene": cell.scene.name, "solver": cell.solver, "n": cell.n,
            "refine": cell.refine, "scene_params": dict(cell.scene_params), "solver_params": dict(cell.solver_params),
            "quantity": cell.scene.quantity}
    return base | ({"expressions": dict(cell.expressions)} if cell.expressions else {})


def _failed(cell: Cell, reason: str, **extra: Any) -> dict[str, Any]:
    return _base(cell) | {"status": "failed", "reason": reason} | extra


def compute_cell(cell: Cell, raise_scene_errors: bool = False) -> dict[str, Any]:
    """Compute one cell in this process through its task and return its JSON-ready result (skips and failures
    are results too): the body of a worker's task (`run_cell`) and of a Dask task.  The solver works on its own
    copy of the scene (one it changed fails the cell), BLAS on one thread; its output passes the boundary checks
    and is compared with the scene's reference once.  Whatever the solver raises is the cell's failed status,
    but with `raise_scene_errors` a SceneError propagates, for the command line to report as bad input."""
    base = _base(cell)
    scene = copy.deepcopy(cell.scene)
    before = scene.content_hash()
    try:
        load_plugins(cell.plugins, cell.plugin_folder)
        solver = named(get_solver(cell.solver), cell.solver)
    except SolverUnavailable as exc:
        return base | {"status": "skipped", "reason": str(exc)}
    ok, reason, broken = _supported(cell, solver, scene)
    if broken:
        return base | {"status": "failed", "reason": broken}
    if not ok:
        return base | {"status": "skipped", "reason": reason}
    resolution = Resolution(cell.n, cell.refine)
    try:
        cell.task.check(solver, dict(cell.solver_params))
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - as in cell_identity
        if isinstance(exc, SceneError):
            if raise_scene_errors:
                raise
            return base | {"status": "failed", "reason": str(exc)}
        return base | {"status": "failed", "reason": _checks_raised(cell, exc)}
    try:
        with threadpool_limits(limits=1, user_api="blas"), recording(cell.solver) as rec:  # BLAS: as with --jobs 1
            cpu = time.process_time()
            out = cell.task.run(solver, scene, resolution, dict(cell.solver_params))
            cpu = time.process_time() - cpu
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: BLE001 - whatever a solver raises is its cell's failure, never a traceback
        if raise_scene_errors and isinstance(exc, SceneError):
            raise
        return base | {"status": "failed", "reason": " ".join(str(exc).split()) if isinstance(exc, Inadmissible)
                       else describe_exception(exc)}
    after = _content_hash(scene)
    if after != before:
        return base | {"status": "failed", "reason": f"solver {cell.solver!r} modified the scene it was given "
                       f"(content hash {before} before the solve, {after} after); allowed: a solver reads its scene "
                       "and never changes it"}
    res = dict(out.get("resolution") or {})
    res.setdefault("h", resolution.spacing(scene.box.width))
    cold = cell.solver not in _SOLVED_HERE
    _SOLVED_HERE.add(cell.solver)
    depends = dependencies(rec, type(solver).__module__)  # what the key cannot see: the cache checks it on reading
    out = out | ({"depends": depends} if depends["files"] or depends["modules"] else {})
    return out | base | {"resolution": res, "errors": compare.errors(scene, out.get("samples")),
                         "scalar_errors": compare.scalar_errors(scene, out.get("summary")),
                         "cost": solve_cost(cpu, out.get("wall_s"), out.get("work") or {}) | {"cold": cold}}


def solve_cost(cpu_s: float, wall_s: Any, work: dict[str, Any]) -> dict[str, float | None]:
    """The CPU cost of one solve: `cpu_s`, the CPU seconds of the solver's run, split into `kernel_s`, the share
    the solver reports as its time loop or linear solve (`work.kernel_s`, else `work.solve_s`, on its own wall
    clock: `kernel_wall_s`) of the solve's wall time `wall_s` applied to the CPU time, so a loaded machine's
    waiting counts in neither, and `setup_s`, the rest; None where the solver reports no kernel."""
    kernel = work.get("kernel_s", work.get("solve_s"))
    real = isinstance(kernel, (int, float)) and not isinstance(kernel, bool) and math.isfinite(kernel)
    wall = float(wall_s) if isinstance(wall_s, (int, float)) and not isinstance(wall_s, bool) else math.nan
    if not (real and math.isfinite(wall) and wall > 0):
        return {"cpu_s": float(cpu_s), "kernel_s": None, "setup_s": None, "kernel_wall_s": kernel if real else None}
    share = min(max(float(kernel) / wall, 0.0), 1.0)
    return {"cpu_s": float(cpu_s), "kernel_s": share * float(cpu_s), "setup_s": (1.0 - share) * float(cpu_s),
            "kernel_wall_s": float(kernel)}


def _content_hash(scene: Scene) -> str:
    try:
        return scene.content_hash()
    except Exception as exc:  # noqa: BLE001 - a scene changed into something that no longer hashes
        return f"none ({describe_exception(exc)})"


def _in_worker(cell: Cell, raise_scene_errors: bool) -> dict[str, Any]:
    """A worker's task: the cell's result, or the SceneError that the command line reports as bad input."""
    try:
        return compute_cell(cell, raise_scene_errors)
    except SceneError as exc:
        return {_SCENE_ERROR: str(exc)}


def _world() -> tuple[Any, ...]:
    """What the workers must share with this process when they are forked: the import path, the working
    folder and the registered solvers (a change starts new workers)."""
    return tuple(sys.path), os.getcwd(), snapshot()


def run_cell(cell: Cell, raise_scene_errors: bool = False, time_limit: float | None = None) -> dict[str, Any]:
    """Run one cell in the first idle worker of this process's pool (the same one call after call while it
    lives) and return its result (`compute_cell`); past `time_limit` seconds (default: the `cell_time_limit` in
    force) it is killed, and a cell that ends its worker is failed with the exit code or signal."""
    limit = _TIME_LIMIT.get() if time_limit is None else time_limit
    return _result(cell, pool(_world()).run_one(_in_worker, (cell, raise_scene_errors), limit), limit)


def _result(cell: Cell, outcome: Outcome, limit: float) -> dict[str, Any]:
    """A worker's outcome as the cell's result; a failure's reason ends with the last error line the solve
    printed when the reason does not say it already (a library that prints its error, then aborts or raises a
    generic exception)."""
    if outcome.kind == "returned":
        if _SCENE_ERROR in outcome.value:
            raise SceneError(outcome.value[_SCENE_ERROR])
        result = outcome.value
        if result.get("status") == "failed" and isinstance(result.get("reason"), str):
            result = {**result, "reason": _with_printed(result["reason"], outcome.error_line)}
        return result
    if outcome.kind == "timed-out":
        return _failed(cell, _with_printed(outcome.reason, outcome.error_line), time_limit_s=limit)
    if outcome.kind == "died":
        return _failed(cell, _with_printed(outcome.reason, outcome.error_line))
    return _failed(cell, f"its worker process could not run it: {outcome.reason}")


def _with_printed(reason: str, line: str) -> str:
    """`reason`, then "; it printed: LINE" unless the line is empty or the reason holds it already."""
    if not line or " ".join(line.split()) in " ".join(reason.split()):
        return reason
    return f"{reason}; it printed: {line}"


def _indexed(i: int, cell: Cell) -> tuple[int, dict[str, Any]]:
    ignore_sigint_in_worker()
    return i, compute_cell(cell)


def _parallel(cells: list[Cell], todo: list[int], jobs: int, client: Any | None
              ) -> Iterator[tuple[int, dict[str, Any]]]:
    """(index, result) pairs in completion order: `jobs` worker processes, or the Dask cluster of `client`
    (a Dask task that raised, or whose worker died, is its cell's failed status)."""
    if client is not None:
        futures = {client.submit(_indexed, i, cells[i], pure=False): i for i in todo}
        for fut in as_completed(list(futures)):
            try:
                yield fut.result()
            except Exception as exc:  # noqa: BLE001 - e.g. distributed's KilledWorker: that cell's failure
                yield futures[fut], _failed(cells[futures[fut]], f"its Dask task failed: {describe_exception(exc)}")
        return
    limit = _TIME_LIMIT.get()
    tasks = [(i, _in_worker, (cells[i], False)) for i in todo]
    for i, outcome in pool(_world()).run(tasks, jobs, limit):
        yield i, _result(cells[i], outcome, limit)


def connect(address: str, timeout: float = 5.0) -> Any:
    """A Dask client of the scheduler at `address`, or a one-line SceneError: a malformed address, no Dask
    installed, nothing listening, or an endpoint that does not complete the Dask handshake (bounded: the
    attempt runs in a thread that is abandoned after `timeout` + 5 s)."""
    allowed = "allowed: the address of a running Dask scheduler, e.g. tcp://host:8786"
    if not isinstance(address, str) or not SCHEDULER_ADDRESS.match(address):
        raise SceneError(f"scheduler={shown(address)} is not valid; {allowed}")
    if Client is None:
        raise SceneError("--scheduler needs the optional dependency dask[distributed]; allowed: install it with "
                         "pip install 'pcverify[dask]', or run without --scheduler")
    box: dict[str, Any] = {}

    def attempt() -> None:
        try:
            box["client"] = Client(address, timeout=f"{timeout}s")
        except BaseException as exc:  # noqa: BLE001 - any failure of a foreign endpoint is one line
            box["error"] = exc

    thread = threading.Thread(target=attempt, daemon=True, name="pcverify-dask-connect")
    thread.start()
    thread.join(timeout + 5.0)
    if thread.is_alive():
        raise SceneError(f"scheduler={shown(address)} did not complete the Dask handshake within "
                         f"{timeout + 5.0:g} s; {allowed}")
    if "error" in box:
        exc = box["error"]
        raise SceneError(f"scheduler={shown(address)} is not reachable ({type(exc).__name__}: "
                         f"{shown(str(exc))}); {allowed}")
    _quiet_dask_logs()
    return box["client"]


def _quiet_dask_logs() -> None:
    """Dask's own log records (a lost scheduler or worker is an ERROR with chained tracebacks, from its
    threads, even after the study) are kept off stderr: each cell it failed says why in one line."""
    names = [n for n in list(logging.root.manager.loggerDict) if n.split(".")[0] in ("distributed", "tornado")]
    for name in {"distributed", "tornado", *names}:
        logging.getLogger(name).setLevel(logging.CRITICAL + 1)


def _smallest(cells: list[Cell], todo: list[int], kind: Any) -> dict[Any, int]:
    """Per kind(cell), the index in `todo` of its smallest cell (n, then refine; the first of equals)."""
    first: dict[Any, int] = {}
    for i in todo:
        k = kind(cells[i])
        if k not in first or (cells[i].n, cells[i].refine) < (cells[first[k]].n, cells[first[k]].refine):
            first[k] = i
    return first


def _warm_up(cells: list[Cell]) -> None:
    """Run the cheapest cell of each solver once, uncached, so compilation stays out of the timings."""
    for i in _smallest(cells, list(range(len(cells))), lambda c: c.solver).values():
        run_cell(cells[i])  # in the worker that runs the timed cells next


def plan(study: Study, cache: Cache, rerun: frozenset[str] | None = None) -> list[dict[str, Any]]:
    """What `execute` would do, cell by cell: key, state (cached, to run, skip) and the skip reason."""
    rows = []
    for c in (c for g in study.groups for c in g.cells):
        key, skip = identify(c)
        cached = cache.load(key)[0] is not None and not _rerun(c, rerun)
        rows.append({"key": key, "state": "cached" if cached else ("skip" if skip else "to run"),
                     "cell": c.describe(), "group": c.group, "solver": c.solver, "reason": skip or ""})
    return rows


def _rerun(cell: Cell, rerun: frozenset[str] | None) -> bool:
    """Whether `--rerun` asks for this cell again (an empty set: every cell)."""
    return rerun is not None and (not rerun or cell.solver in rerun)


def execute(study: Study, cache: Cache, jobs: int = 1, progress: bool = True, scheduler: str | None = None,
            rerun: frozenset[str] | None = None, allow_large: bool = False, time_limit: float | None = None
            ) -> tuple[list[dict[str, Any]], dict[str, int]]:
    """Run every cell not yet cached; return all results in cell order and the counts.

    `rerun` recomputes cached cells too: all of them (an empty set) or those of the named solvers.  A cell
    beyond the work limits stops the study before anything runs, unless `allow_large`.  A computed cell is
    killed after `time_limit` seconds (default: the `cell_time_limit` in force); a cached cell that failed on a
    shorter limit is computed again.  Timed cells run last (see the module docstring); an untimed twin of a
    timed cell takes its result: each solution once.
    """
    limit = _TIME_LIMIT.get() if time_limit is None else float(time_limit)
    cache.stale_after = max(cache.stale_after, 2 * limit)  # a live cell's lock never looks stale
    with cell_time_limit(limit):
        return _execute(study, cache, jobs, progress, scheduler, rerun, allow_large, limit)


def _execute(study: Study, cache: Cache, jobs: int, progress: bool, scheduler: str | None,
             rerun: frozenset[str] | None, allow_large: bool, limit: float
             ) -> tuple[list[dict[str, Any]], dict[str, int]]:
    cells = [c for g in study.groups for c in g.cells]
    identities = [identify(c) for c in cells]
    keys = [ident.key for ident in identities]
    results: list[dict[str, Any] | None] = []
    counts = {"cells": len(cells), "cached": 0, "done": 0, "failed": 0, "corrupt": 0}
    todo = []
    for i, key in enumerate(keys):
        entry, state = cache.load(key) if not _rerun(cells[i], rerun) else (None, "rerun")
        entry = as_cell(entry, cells[i])
        if entry is not None and entry.get("status") == "failed" and (entry.get("time_limit_s") or limit) < limit:
            entry = None  # it ran out of a shorter time limit than this run allows: computed again
        if state.startswith("corrupt"):
            counts["corrupt"] += 1
            tqdm.write(f"cache entry {key} ({cells[i].describe()}) is {state}; recomputing", file=sys.stderr)
        elif state.startswith("stale"):
            tqdm.write(f"cache entry {key} ({cells[i].describe()}) is {state}; recomputing", file=sys.stderr)
        if entry is not None:
            counts["cached"] += 1
            counts["failed"] += entry.get("status") == "failed"  # a failed cell stays failed when read back
        else:
            todo.append(i)
        results.append(entry)
    refused: dict[int, str] = {}  # cells whose solver's estimate raised: failed, never solved
    for i in todo:  # the work limits, before anything starts
        if identities[i].skip is None and isinstance(cells[i].task, SolveTask):
            try:
                check_work(get_solver(cells[i].solver), cells[i].scene, Resolution(cells[i].n, cells[i].refine),
                           dict(cells[i].solver_params), allow_large, label=cells[i].solver)
            except (EstimateError, SolverUnavailable) as exc:
                refused[i] = str(exc)
    cache.remove_stray_files()
    client = connect(scheduler) if scheduler is not None else None  # before the progress bar: errors are one line
    bar = progress_bar(len(cells), study.name, "cell", initial=counts["cached"], enabled=progress)

    first: dict[str, int] = {}
    same: dict[int, list[int]] = {}  # cells of other groups with the same key: solved once, shared
    for i in todo:
        if keys[i] in first:
            same[first[keys[i]]].append(i)
        else:
            first[keys[i]] = i
            same[i] = []
    todo = [i for i in todo if first[keys[i]] == i]
    timed = {untimed_key(cells[i]): i for i in todo if cells[i].serial and identities[i].skip is None}
    for i in [i for i in todo if not cells[i].serial and keys[i] in timed]:  # solved once, in the timed pass
        same[timed[keys[i]]] += [i, *same.pop(i)]
        todo.remove(i)

    def share(i: int, res: dict[str, Any], done: bool) -> None:
        results[i] = as_cell(res, cells[i])
        counts["done" if done else "cached"] += 1
        for j in same[i]:
            results[j] = as_cell(res, cells[j])
            counts["cached"] += 1
            if keys[j] != keys[i]:  # the untimed twin of a timed cell: its own entry
                cache.store(keys[j], res | {"cache_key": keys[j]})
        counts["failed"] += (res.get("status") == "failed") * (1 + len(same[i]))
        bar.set_postfix(done=counts["done"], cached=counts["cached"], failed=counts["failed"])
        bar.update(1 + len(same[i]))

    def finish(i: int, res: dict[str, Any]) -> None:
        res["cache_key"] = keys[i]
        cache.release(keys[i], res)
        share(i, res, done=True)
        check_interrupted()  # a Ctrl-C that a library swallowed stops the study here, this cell stored

    try:
        mine, theirs = [], []  # cells to compute here, cells another process is computing (waited for)
        for i in todo:
            claim = cache.claim(keys[i], reuse=not _rerun(cells[i], rerun))
            if claim == CLAIMED:
                mine.append(i)
            elif claim == HELD:
                theirs.append(i)
            else:  # another process stored it since it was looked up: not computed twice
                share(i, claim, done=False)
        _run(study, cells, identities, mine, finish, bar, jobs, client, refused)
        for i in theirs:
            bar.set_description(f"{study.name}: waiting for another process: {cells[i].describe()}"[:70])
            entry = cache.wait(keys[i], between=check_interrupted)
            if entry is not None:
                share(i, entry, done=False)
            else:  # its computing process died or failed to store it: compute it here
                _run(study, cells, identities, [i], finish, bar, 1, None, refused)
    finally:
        cache.unlock_all()
        bar.close()
        if client is not None:
            client.close()
    done = [r for r in results if r is not None]
    counts["statuses"] = dict(sorted(Counter(str(r.get("status")) for r in done).items()))
    return done, counts


def _run(study: Study, cells: list[Cell], identities: list[CellId], todo: list[int],
         finish: Any, bar: Any, jobs: int, client: Any | None, refused: dict[int, str]) -> None:
    """Run the cells `todo`: the free ones in parallel, then the timed ones serially after a warm-up (one
    worker process: the first idle one, as `run_cell` takes).  A refused cell is failed with its reason."""
    for i in [i for i in todo if i in refused]:
        finish(i, _failed(cells[i], refused[i]))
    todo = [i for i in todo if i not in refused]
    free = first_of_each_kind(cells, [i for i in todo if not cells[i].serial])
    timed = [i for i in todo if cells[i].serial and identities[i].skip is None]
    timed_skips = [i for i in todo if cells[i].serial and identities[i].skip is not None]
    if (jobs > 1 or client is not None) and len(free) > 1:
        for i, res in _parallel(cells, free, jobs, client):
            finish(i, res)
    else:
        timed_skips = free + timed_skips
    for i in timed_skips:
        bar.set_description(f"{study.name}: {cells[i].describe()}"[:70])
        finish(i, run_cell(cells[i]))
    if timed:
        bar.set_description(f"{study.name}: warm-up before the timed serial pass")
        _warm_up([cells[i] for i in timed])
    stamp = run_stamp()
    for i in timed:
        bar.set_description(f"{study.name}: timed {cells[i].describe()}"[:70])
        finish(i, timed_result(cells[i], stamp))


def run_stamp() -> dict[str, str]:
    """What identifies one timed pass: its id, the machine (host, processor, cores) and the time it started;
    timings of different passes are not compared side by side unless a figure is asked to."""
    return {"run": uuid.uuid4().hex[:12], "machine": f"{platform.node()} {platform.machine()} "
            f"{platform.processor() or ''} {os.cpu_count()} cores".replace("  ", " "),
            "started": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")}


def timed_result(cell: Cell, stamp: dict[str, str]) -> dict[str, Any]:
    """A timed cell's result: solved `cell.repeats` times in the timed worker (after its warm-up), again only
    while a solve takes under REPEAT_BELOW_S of CPU (a longer one's noise is a smaller part of it); its cost
    the least CPU and wall time of the solves, every sample kept, with the pass's stamp."""
    runs = [run_cell(cell)]
    while (len(runs) < cell.repeats and all(r.get("status") == "ok" for r in runs)
           and (runs[-1].get("cost") or {}).get("cpu_s", math.inf) < REPEAT_BELOW_S):
        runs.append(run_cell(cell))
    first = runs[0]
    if first.get("status") != "ok" or not all("cost" in r for r in runs):
        return first | {"timing": {"kind": "serial after warm-up", **stamp}}
    best = min(runs, key=lambda r: r["cost"]["cpu_s"])
    samples = [r["cost"]["cpu_s"] for r in runs]
    return first | {"wall_s": min(r["wall_s"] for r in runs), "cost": best["cost"],
                    "timing": {"kind": "serial after warm-up", "repeats": len(runs), "cpu_s_samples": samples,
                               **stamp}}


def first_of_each_kind(cells: list[Cell], todo: list[int]) -> list[int]:
    """`todo` reordered: first the smallest cell of each kind (solver, scene, task), then the rest in order.  The
    workers then start on different kinds, whose compiled kernels differ, so they compile them side by side
    instead of the same ones at the same time (each compilation happens once: `pcverify.numba_guard`)."""
    lead = set(_smallest(cells, todo, lambda c: (c.solver, c.scene.name, c.task.name)).values())
    return [i for i in todo if i in lead] + [i for i in todo if i not in lead]


def cached_results(study: Study, cache: Cache) -> list[dict[str, Any]]:
    """The results of a study's cells as the cache holds them; a cell whose entry is missing or corrupt is a
    result of status `missing` that says so (a report rebuilt from the cache never judges a claim on what is
    left after a cell dropped out)."""
    out = []
    for c in (c for g in study.groups for c in g.cells):
        key = identify(c).key
        entry, state = cache.load(key)
        out.append(as_cell(entry, c) if entry is not None else missing_result(c, key, state))
    return out


def missing_result(cell: Cell, key: str, state: str) -> dict[str, Any]:
    """The result of a cell the cache cannot give back (`state`: miss or corrupt: why), status missing."""
    why = "has no entry" if state == "miss" else f"entry is {state}"
    return as_cell({"status": "missing", "reason": f"the cache {why} (key {key}): rerun the study to compute it",
                    "cache_key": key}, cell) or {}


def as_cell(entry: dict[str, Any] | None, cell: Cell) -> dict[str, Any] | None:
    """A cached result seen as the result of `cell`: the same solve may have been cached by another group
    or study (same content key), so the identity fields are the cell's own, not those of its first run."""
    if entry is None:
        return None
    return entry | {"group": cell.group, "scene": cell.scene.name, "solver": cell.solver, "n": cell.n,
                    "refine": cell.refine, "scene_params": dict(cell.scene_params),
                    "solver_params": dict(cell.solver_params)}
