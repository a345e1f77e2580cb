"""The pieces written once: the cell key (`execution.identify`), the cache protocol (`Cache.claim`, `release`,
`wait`) and the energy balance (`solvers.energy`), each checked on a case whose answer is known."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from pcverify.harness.cli import main
from pcverify.harness.run.cache import CLAIMED, HELD, Cache
from pcverify.harness.run.execution import cached_results, first_of_each_kind, identify, plan
from pcverify.harness.study.study import load_study
from pcverify.solvers.energy import balance_error
from pcverify.solvers.particles.macromolecule import codes
from pcverify.solvers.particles.macromolecule.simulate import energy_balance_error

ENTRY = {"status": "ok", "group": "g", "scene": "s", "solver": "x", "n": 1, "refine": 0}
KEY = "0123456789abcdef0123"

ALPHA = 'name = "alpha"\n[[group]]\nid = "faces"\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\nn = [2, 3]\n'


def _claim_compute_or_wait(root: str, start, log: str, out) -> None:
    """One process of the race: claim the key; compute (append a line to `log`) and release, or wait."""
    cache = Cache(root)
    start.wait()
    claim = cache.claim(KEY)
    if claim == CLAIMED:
        with open(log, "a") as fh:
            fh.write(f"{os.getpid()}\n")
        time.sleep(1.0)  # the other process finds the lock held meanwhile
        cache.release(KEY, ENTRY | {"by": os.getpid()})
        out.put(("computed", os.getpid()))
    elif claim == HELD:
        out.put(("waited", cache.wait(KEY, poll=0.05)["by"]))
    else:
        out.put(("reused", claim["by"]))


def test_two_processes_claim_one_key_only_one_computes(tmp_path):
    ctx = multiprocessing.get_context("fork")
    start, out, log = ctx.Barrier(2), ctx.Queue(), str(tmp_path / "computed")
    procs = [ctx.Process(target=_claim_compute_or_wait, args=(str(tmp_path / "cache"), start, log, out))
             for _ in range(2)]
    for p in procs:
        p.start()
    answers = sorted(out.get(timeout=60) for _ in procs)
    for p in procs:
        p.join(30)
    computed = Path(log).read_text().split()
    assert len(computed) == 1  # one process computed the cell
    assert answers[0][0] == "computed" and answers[1][0] in ("waited", "reused")
    assert answers[1][1] == answers[0][1] == int(computed[0])  # the other one got the computer's entry
    assert not list((tmp_path / "cache").glob("*.lock"))  # the lock is released


def test_claim_reads_the_entry_again_once_the_lock_is_taken(tmp_path):
    cache = Cache(tmp_path)
    Cache(tmp_path).store(KEY, ENTRY)  # another process stored it after this one looked it up
    assert cache.claim(KEY) == ENTRY
    assert not (tmp_path / f"{KEY}.lock").exists() and KEY not in cache.locks  # released: not computed twice
    assert cache.claim(KEY, reuse=False) == CLAIMED  # --rerun: computed again, whatever is stored
    assert KEY in cache.locks


def test_wait_claims_a_cell_whose_holder_died_without_storing_it(tmp_path):
    ctx = multiprocessing.get_context("fork")
    holder = ctx.Process(target=lambda: (Cache(tmp_path).claim(KEY), os._exit(0)))
    holder.start()
    holder.join(30)
    assert (tmp_path / f"{KEY}.lock").exists()  # left behind by its dead holder
    cache = Cache(tmp_path)
    assert cache.wait(KEY, poll=0.05) is None  # nothing to wait for: this process computes it
    assert KEY in cache.locks
    cache.release(KEY, ENTRY)
    assert cache.load(KEY) == (ENTRY, "hit") and not (tmp_path / f"{KEY}.lock").exists()


def test_wait_returns_the_entry_its_holder_stores(tmp_path):
    holder, waiter = Cache(tmp_path), Cache(tmp_path)
    assert holder.claim(KEY) == CLAIMED
    assert waiter.claim(KEY) == HELD
    polls = []

    def between() -> None:  # the holder stores the entry while the other process waits
        polls.append(1)
        if len(polls) == 3:
            holder.release(KEY, ENTRY | {"by": "holder"})

    assert waiter.wait(KEY, poll=0.01, between=between)["by"] == "holder"
    assert len(polls) == 3


def test_identify_gives_the_key_the_cache_and_the_plan_use(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    Path("alpha.toml").write_text(ALPHA)
    assert main(["study", "alpha.toml", "--out", "out"]) == 0
    study, cache = load_study("alpha.toml"), Cache(tmp_path / "out" / "cache")
    keys = [identify(c).key for g in study.groups for c in g.cells]
    assert len(set(keys)) == 2 and all(identify(c).skip is None for c in study.groups[0].cells)
    assert sorted(p.stem for p in cache.root.glob("*.json")) == sorted(keys)
    assert [row["key"] for row in plan(study, cache)] == keys
    assert [r["cache_key"] for r in cached_results(study, cache)] == keys


def test_balance_error_of_a_body_pushed_from_rest_is_zero_and_a_leak_is_its_fraction():
    m, force = 2.0, 3.0
    t = np.linspace(0.0, 1.0, 11)
    x = force * t**2 / (2 * m)  # from rest under a constant force
    kinetic, work = 0.5 * m * (force * t / m) ** 2, force * x
    assert balance_error(kinetic, (work,), work[-1]) == 0.0  # energy held = work done
    assert balance_error(0.9 * kinetic, (work,), work[-1]) == pytest.approx(0.1)  # 10 % of the work lost
    assert balance_error(kinetic, (0.5 * work, 0.5 * work), 1.0) == 0.0  # work of two sources, in turn
    assert math.isnan(balance_error(kinetic, (work,), 0.0))  # nothing put in: no fraction


def test_macromolecule_balance_is_relative_to_the_largest_energy_flow():
    energy = np.zeros(8)
    energy[[codes.E_START, codes.E_END, codes.E_DISS, codes.E_DRIVE, codes.E_BATH]] = 10.0, 12.0, 1.0, 2.0, 0.5
    # 12 - 10 + 1 - 2 - 0.5 = 0.5 off, the largest flow is E_end = 12
    assert energy_balance_error(SimpleNamespace(energy=energy)) == 0.5 / 12.0


def test_balance_error_gives_each_solver_its_former_value_to_the_bit():
    rng = np.random.default_rng(7)
    ke, u, fric, diss, work, load = (rng.normal(size=50) * 10.0 ** rng.integers(-3, 3) for _ in range(6))
    ke0 = float(rng.normal())
    # MCA fracture, elastic phase: relative to the peak elastic energy
    old = float(np.max(np.abs(ke + u - ke0 - work)) / max(np.max(u), 1e-300))
    assert balance_error(ke + u - ke0, (work,), max(np.max(u), 1e-300)) == old
    # MCA sliding contact: relative to the work over the window
    held0, put0 = ke[0] + u[0] + fric[0] + diss[0], work[0] + load[0]
    total = work[-1] + load[-1] - put0
    old = float(np.max(np.abs((ke + u + fric + diss - held0) - (work + load - put0))) / abs(total))
    assert balance_error(ke + u + fric + diss - held0, (work + load - put0,), abs(total)) == old
    # macromolecule: relative to the largest flow
    start, end, dis, drive, bath = (np.float64(v) for v in rng.normal(size=5))
    scale = max(abs(start), abs(end), abs(drive), abs(bath), dis, 1e-300)
    old = float(abs(end - start + dis - drive - bath) / scale)
    assert balance_error(end - start + dis, (drive, bath), scale) == old


TWINS = ALPHA + ('[[group]]\nid = "timed"\nanalysis = "work-precision"\nscene = "bar-heat-faces"\nsolvers = ["skfem"]\n'
                 'n = [2, 3]\nerror = "nodes.l2"\n')


def test_a_cell_a_timed_group_also_solves_is_solved_once(tmp_path, capsys):
    """The faces group asks for the two cells the timed group solves: two solves, not four; the untimed cells
    carry the timed results under their own keys, so a rerun reads all four back."""
    path = tmp_path / "alpha.toml"
    path.write_text(TWINS)
    args = ["study", str(path), "--out", str(tmp_path / "out"), "--json"]
    assert main(args) == 0
    (entry,) = json.loads(capsys.readouterr().out)
    assert (entry["cells"], entry["done"], entry["cached"]) == (4, 2, 2)
    study = load_study(str(path))
    cache = Cache(tmp_path / "out" / "cache")
    results = cached_results(study, cache)
    by = {(r["group"], r["n"]): r for r in results}
    for n in (2, 3):
        assert by[("faces", n)]["summary"] == by[("timed", n)]["summary"]
        assert by[("faces", n)]["cache_key"] != by[("timed", n)]["cache_key"]
    assert len(list((tmp_path / "out" / "cache").glob("*.json"))) == 4
    assert main(args) == 0
    (entry,) = json.loads(capsys.readouterr().out)
    assert (entry["done"], entry["cached"]) == (0, 4)


def test_workers_start_on_different_kinds_of_cells(tmp_path):
    """The parallel cells are handed out smallest-of-each-kind first (solver, scene, task), so the two workers
    begin on different kernels; the rest follow in study order."""
    path = tmp_path / "kinds.toml"
    path.write_text(ALPHA.replace('solvers = ["skfem"]', 'solvers = ["skfem", "fipy"]').replace("n = [2, 3]",
                                                                                            "n = [3, 2, 4]"))
    cells = [c for g in load_study(str(path)).groups for c in g.cells]
    order = first_of_each_kind(cells, list(range(len(cells))))
    assert [(cells[i].solver, cells[i].n) for i in order] == [
        ("skfem", 2), ("fipy", 2), ("skfem", 3), ("skfem", 4), ("fipy", 3), ("fipy", 4)]
