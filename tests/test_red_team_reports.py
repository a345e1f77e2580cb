"""Red team, report files (family 7) and the files a report embeds (family 4, second half).

- an empty, truncated, garbage or ill-formed manifest.json (or verdicts.json, or a saved benchmark run under
  --out/benchmarks) is skipped with a one-line warning naming it; later `study` and `report` runs on that --out succeed;
- `pcverify report` embeds only files inside --out: a manifest naming an absolute path, `../`, or a symlink
  leading out has that file left out with a warning;
- a write that fails (a full disk) leaves no partial file and no temporary file, and the rerun succeeds;
  temporary files of dead writers are removed; a dead process does not hold the index lock;
- concurrency: 4 different studies x 8 rounds on one --out in parallel processes, and 2 copies of one study at
  once: every process exits 0, no cell is computed twice, the tables equal serial runs'.
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
import xml.etree.ElementTree as ET
from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from PIL import Image
from red_team import ENV, check_tally, run, tally

from pcverify.harness.cli import main
from pcverify.harness.report.write import write_index
from pcverify.harness.run import files

STUDIES = {  # small studies of cheap continuum cells: tables, a claim, figures, VTU files
    "alpha": """name = "alpha"
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["skfem"]
n = [2, 3]

[[claim]]
id = "faces-exact"
text = "scikit-fem reproduces the linear profile"
table = "faces-cells"
metric = "err.nodes.linf"
reference = "analytic"
tolerance = 1e-9
""",
    "beta": """name = "beta"
[[group]]
id = "transient"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.05, dt = 0.01 }
solvers = ["skfem"]
n = [2, 3, 4]
""",
    "gamma": """name = "gamma"
[[group]]
id = "compression"
scene = "bar-compression"
solvers = ["skfem-elastic"]
n = [2, 3]
vtu = true
""",
    "delta": """name = "delta"
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["fipy"]
n = [2, 3]
""",
    "twin": """name = "twin"
[[group]]
id = "transient"
analysis = "convergence"
scene = "bar-heat-faces"
scene_params = { mode = "transient", t_end = 0.05, dt = 0.01 }
solvers = ["skfem", "fipy"]
n = [2, 3, 4]
""",
}


def _write_studies(folder: Path) -> None:
    for name, text in STUDIES.items():
        (folder / f"{name}.toml").write_text(text)


def _study(argv: list[str], capsys) -> tuple[int, str, str]:
    """`pcverify ARGV` in this process: (exit code, stdout, stderr)."""
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def template(tmp_path_factory) -> Path:
    """An --out with studies alpha and gamma run (cache filled, reports written), copied by each test."""
    root = tmp_path_factory.mktemp("template")
    _write_studies(root)
    with contextlib.chdir(root):
        for name in ("alpha", "gamma"):
            assert main(["study", f"{name}.toml", "--out", "out"]) == 0
    return root


@pytest.fixture
def work(template, tmp_path, monkeypatch) -> Path:
    shutil.copytree(template, tmp_path, dirs_exist_ok=True)
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _warnings(err: str) -> list[str]:
    return [line for line in err.splitlines() if line.startswith("pcverify: warning: ")]


# ----------------------------------------------------------------------------- family 7: unreadable manifests
GARBAGE = {
    "empty": b"",
    "blank": b"  \n",
    "truncated": b'{"name": "alpha", "title": "a", "sect',
    "binary": bytes(range(256)),
    "null": b"null",
    "a list": b"[1, 2]",
    "another study's name": b'{"name": "../../etc", "title": "t", "sections": []}',
    "sections not a list": b'{"name": "alpha", "title": "t", "sections": "abc"}',
    "a section without its title": b'{"name": "alpha", "title": "t", "sections": [{"id": "g", "figures": []}]}',
    "figures not names": b'{"name": "alpha", "title": "t", "sections": [{"id": "g", "title": "g", "figures": [1]}]}',
    "orders of the wrong type": b'{"name": "alpha", "title": "t", "sections": [], "orders": [{"order": "x"}]}',
}


def test_garbage_manifests_do_not_break_later_studies_and_reports(work, capsys) -> None:
    """alpha's manifest.json emptied, and a study folder per kind of garbage: a later study (delta) and `report`
    exit 0, each naming every bad file in one warning line; the index shows the good studies."""
    bad = [Path("out/alpha/manifest.json")]  # as the warnings name them (--out as given)
    bad[0].write_bytes(b"")
    for k, body in enumerate(GARBAGE.values()):
        bad.append(Path(f"out/junk{k}/manifest.json"))
        bad[-1].parent.mkdir()
        bad[-1].write_bytes(body.replace(b'"alpha"', f'"junk{k}"'.encode()))
    for argv in (["study", "delta.toml", "--out", "out"], ["report", "--out", "out"]):
        code, _, err = _study(argv, capsys)
        assert code == 0 and "Traceback" not in err, err[-1500:]
        for path in bad:
            assert len([w for w in _warnings(err) if f"{path} " in w and w.endswith("; skipped")]) == 1, (path, err)
        index = (work / "out" / "index.html").read_text()
        assert "id='delta'" in index and "id='gamma'" in index and "id='junk" not in index
        bad[0].write_bytes(b"")  # (`report` rebuilt alpha from the cache: spoil it again)
    tally("report files", "accepted", len(bad))


JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=12)
    | st.sampled_from(["faces-cells.csv", "../../secret.csv", "/etc/hostname", "SECRET_PATH", "alpha", ""]),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(
        st.sampled_from(["id", "title", "figures", "tables", "vtu", "name", "order", "solver"]) | st.text(max_size=6),
        inner, max_size=4),
    max_leaves=8)
FIELDS = ["name", "title", "sections", "verdicts", "solvers", "orders", "plugins", "command", "rerun", "study_file",
          "sections.0", "sections.0.id", "sections.0.title", "sections.0.figures", "sections.0.tables",
          "sections.0.vtu"]


@settings(derandomize=True, database=None, deadline=None, max_examples=40,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(FIELDS), value=JSON)
def test_any_field_of_a_manifest_replaced_by_any_json_never_breaks_the_index(template, tmp_path_factory, field,
                                                                             value) -> None:
    """alpha's manifest with one field (top level or of its first section) replaced by an arbitrary JSON value,
    a path outside --out among them: the index is written, alpha shown or skipped with a warning, and no file
    outside --out embedded."""
    where = tmp_path_factory.mktemp("fuzz")
    shutil.copytree(template / "out", where / "out")
    token = f"SECRET{uuid.uuid4().hex}"
    (where / "secret.csv").write_text(f"column\n{token}\n")
    path = where / "out" / "alpha" / "manifest.json"
    doc = json.loads(path.read_text())
    value = json.loads(json.dumps(value).replace("SECRET_PATH", str(where / "secret.csv")))
    *parents, last = field.split(".")
    target = doc
    for part in parents:
        target = target[int(part)] if part.isdigit() else target[part]
    target[int(last) if last.isdigit() else last] = value
    path.write_text(json.dumps(doc))
    with contextlib.redirect_stderr(io.StringIO()) as err:
        index = write_index(where / "out").read_text()
    assert index.endswith("</html>") and token not in index
    assert "id='alpha'" in index or f"{path} " in err.getvalue()
    tally("report files", "accepted")


BENCHMARK_GARBAGE = {
    **GARBAGE,
    "no benchmarks": b'{"datetime": "x"}',
    "benchmarks not a list": b'{"benchmarks": {"a": 1}}',
    "a benchmark without stats": b'{"benchmarks": [{"name": "t"}]}',
    "a mean that is text": b'{"benchmarks": [{"name": "t", "stats": {"mean": "fast", "min": 1}}]}',
    "a mean that is not finite": b'{"benchmarks": [{"name": "t", "stats": {"mean": NaN, "min": 1}}]}',
    "a name that is a number": b'{"benchmarks": [{"name": 3, "stats": {"mean": 1, "min": 1}}]}',
}


def test_garbage_benchmark_saves_are_skipped_with_a_warning(work, capsys) -> None:
    """Beside one valid pytest-benchmark save, a file of each kind of garbage under --out/benchmarks: the index
    is written with the valid run's benchmark table, and each garbage file gets one warning naming it.
    A valid save whose extra_info has a key "run" (a column the report makes) does not replace it."""
    storage = Path("out/benchmarks/Linux-CPython-3.11-64bit")
    storage.mkdir(parents=True)
    valid = {"datetime": "2026-11-24T00:00:00", "commit_info": {"id": "0123456789abcdef"},
             "benchmarks": [{"name": "test_bench_kernel", "stats": {"mean": 2.5e-3, "min": 2.4e-3},
                             "extra_info": {"particles": 160, "ns_per_pair_step": 5.74, "run": "hostile"}}]}
    (storage / "0001_valid.json").write_text(json.dumps(valid))
    for k, (name, body) in enumerate(BENCHMARK_GARBAGE.items()):
        (storage / f"{k + 2:04d}_{name.replace(' ', '-')}.json").write_bytes(body)
    capsys.readouterr()
    index = write_index(Path("out")).read_text()
    err = capsys.readouterr().err
    warned = _warnings(err)
    for k, name in enumerate(BENCHMARK_GARBAGE):
        path = storage / f"{k + 2:04d}_{name.replace(' ', '-')}.json"
        assert sum(str(path) in w for w in warned) == 1, (name, err[-1500:])
        tally("report files", "rejected")
    latest = pd.read_csv("out/benchmark-figures/latest.csv")
    assert list(latest["benchmark"]) == ["test_bench_kernel"] and list(latest["run"]) == [0]
    assert "id='benchmarks'" in index and "test_bench_kernel" in index


@pytest.mark.parametrize("body", ["", "{", "[{\"study\": \"other\"}]", "{\"a\": 1}"])
def test_a_garbage_verdicts_file_is_skipped_with_a_warning(work, body, capsys) -> None:
    path = Path("out/alpha/verdicts.json")
    path.write_text(body)
    code, _, err = _study(["study", "delta.toml", "--out", "out"], capsys)
    assert code == 0 and [w for w in _warnings(err) if str(path) in w], err[-1500:]
    tally("report files", "accepted")


def test_a_garbage_manifest_through_the_command_line(work, capfd) -> None:
    """The same through the command line the red team ran (in this process; PCVERIFY_RED_TEAM_CLI: another)."""
    manifest = Path("out/gamma/manifest.json")
    manifest.write_text("")
    for args in (("study", "delta.toml", "--out", "out"), ("report", "--out", "out")):
        done = run(*args, cwd=work, capfd=capfd)
        assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-1500:]
        assert f"pcverify: warning: {manifest} is empty; skipped" in done.stderr
    tally("report files", "accepted")


# ----------------------------------------------------------------------------- family 4: files outside --out
def _evil_manifest(out: Path, name: str, names: dict[str, list[str]], verdicts: str | None = None) -> Path:
    folder = out / name
    folder.mkdir(exist_ok=True)
    doc = {"name": name, "title": name, "study_file": None, "verdicts": verdicts, "solvers": [], "orders": [],
           "sections": [{"id": "g", "title": "g", "figures": names.get("figures", []),
                         "tables": names.get("tables", []), "vtu": []}]}
    (folder / "manifest.json").write_text(json.dumps(doc))
    return folder


@pytest.fixture
def secret(work) -> tuple[Path, str]:
    """A table and a PNG outside --out with a token that must not reach the index."""
    token = f"SECRET{uuid.uuid4().hex}"
    (work / "secret.csv").write_text(f"column\n{token}\n")
    Image.new("RGB", (3, 3), (255, 0, 0)).save(work / "secret.png")
    return work, token


OUTSIDE = {
    "absolute table": ({"tables": ["{work}/secret.csv"]}, None),
    "absolute /etc file": ({"tables": ["/etc/hostname"]}, None),
    "relative table": ({"tables": ["../../secret.csv"]}, None),
    "relative figure": ({"figures": ["../../secret.png"]}, None),
    "absolute figure": ({"figures": ["{work}/secret.png"]}, None),
    "verdicts": ({}, "../../secret.csv"),
    "symlinked table": ({"tables": ["link.csv"]}, None),
    "symlinked figure": ({"figures": ["link.png"]}, None),
    "symlinked folder": ({"tables": ["up/secret.csv"]}, None),
    "missing file": ({"tables": ["nothing-here.csv"]}, None),
}


def test_manifests_naming_files_outside_out_are_not_embedded(secret, capsys) -> None:
    """A study folder per case, its manifest naming a file outside --out (or a missing one): `report` exits 0,
    warns once per name, and the index holds neither the outside table's token nor an image in those studies."""
    work, token = secret
    for k, (names, verdicts) in enumerate(OUTSIDE.values()):
        names = {key: [v.replace("{work}", str(work)) for v in vs] for key, vs in names.items()}
        folder = _evil_manifest(work / "out", f"evil{k}", names, verdicts)
        (folder / "link.csv").symlink_to(work / "secret.csv")
        (folder / "link.png").symlink_to(work / "secret.png")
        (folder / "up").symlink_to(work)
    code, _, err = _study(["report", "--out", "out"], capsys)
    assert code == 0 and "Traceback" not in err, err[-1500:]
    index = (work / "out" / "index.html").read_text()
    assert token not in index
    for k, (names, verdicts) in enumerate(OUTSIDE.values()):
        named = [*names.get("figures", []), *names.get("tables", []), *([verdicts] if verdicts else [])][0]
        named = named.replace("{work}", str(work))
        assert len([w for w in _warnings(err) if f"evil{k}/" in w and repr(named) in w and "not embedded" in w]) == 1
        section = index.split(f"id='evil{k}'")[1].split("</section>")[0]
        assert "base64" not in section and "<details" not in section
        tally("embedded paths", "rejected")


def test_files_inside_out_are_still_embedded(work, capsys) -> None:
    """A manifest naming another study's table and figure inside --out (and one via a symlink that stays
    inside) embeds them: the check is containment, not a name pattern."""
    assert _study(["study", "beta.toml", "--out", "out"], capsys)[0] == 0
    folder = _evil_manifest(work / "out", "evil", {"figures": ["../beta/transient.png"], "tables": ["inner.csv"]})
    (folder / "inner.csv").symlink_to(work / "out" / "alpha" / "faces-cells.csv")
    code, _, err = _study(["report", "--out", "out"], capsys)
    evil = (work / "out" / "index.html").read_text().split("id='evil'")[1].split("</section>")[0]
    assert code == 0 and not _warnings(err) and "base64" in evil and "err.nodes.linf" in evil
    tally("embedded paths", "accepted")


# ----------------------------------------------------------------------------- family 7: faults
def test_atomic_write_of_a_failing_producer_leaves_the_old_file(tmp_path) -> None:
    """A write that fails half-way (ENOSPC from the producer, as savefig meets a full disk): the target keeps its
    old content and no temporary file is left."""
    target = tmp_path / "figure.svg"
    target.write_text("<svg>old</svg>")

    def half(fh) -> None:
        fh.write(b"<svg>ne")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    with pytest.raises(OSError) as exc:
        files.atomic_write(target, half)
    assert exc.value.errno == errno.ENOSPC and exc.value.filename == str(target)
    assert target.read_text() == "<svg>old</svg>" and os.listdir(tmp_path) == ["figure.svg"]
    tally("report files", "accepted")


def _complete(path: Path) -> bool:
    """Whether a report file is whole (parses as what its suffix says)."""
    if path.suffix == ".json":
        json.loads(path.read_text())
    elif path.suffix == ".csv":
        pd.read_csv(path)
    elif path.suffix in (".svg", ".vtu"):
        ET.parse(path)
    elif path.suffix == ".png":
        with Image.open(path) as im:
            im.load()
    elif path.suffix == ".html":
        assert path.read_text().endswith("</html>")
    return True


def _counting_fsync(fail_at: int | None, code: int = errno.ENOSPC):
    calls = {"n": 0}
    real = os.fsync

    def fsync(fd: int) -> None:
        calls["n"] += 1
        if fail_at is not None and calls["n"] == fail_at:
            raise OSError(code, os.strerror(code))
        real(fd)

    return fsync, calls


def test_a_full_disk_at_every_report_write_leaves_no_partial_file(work, monkeypatch, capsys) -> None:
    """Study beta's report (tables, Markdown, a figure's JSON/SVG/PNG, manifest, verdicts, index) with the disk
    filling up at the k-th file, for every k: exit 2 with one line naming the file, no temporary file, every
    file present is whole; then, the disk freed, the rerun succeeds."""
    assert _study(["study", "beta.toml", "--out", "cells"], capsys)[0] == 0  # the cells, in a cache of their own
    argv = ["study", "beta.toml", "--out", "out", "--cache", "cells/cache", "--json"]
    fsync, calls = _counting_fsync(None)
    monkeypatch.setattr(files.os, "fsync", fsync)
    assert _study(argv, capsys)[0] == 0
    writes = calls["n"]
    assert writes >= 12  # 3 tables x (CSV, Markdown), cells.csv, JSON/SVG/PNG, manifest, verdicts.json, index
    for k in range(1, writes + 1):
        shutil.rmtree(work / "out")
        fsync, calls = _counting_fsync(k)
        monkeypatch.setattr(files.os, "fsync", fsync)
        code, _, err = _study(argv, capsys)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and "No space left on device" in lines[0], (k, err)
        leftovers = [p for p in (work / "out").rglob(".*.tmp")]
        assert not leftovers, (k, leftovers)
        assert all(_complete(p) for p in (work / "out").rglob("*") if p.is_file() and p.name != ".index.lock")
    tally("report files", "accepted")  # one case: the disk full at each of the report's `writes` files
    monkeypatch.setattr(files.os, "fsync", _counting_fsync(None)[0])  # the disk freed
    assert _study(argv, capsys)[0] == 0 and _complete(work / "out" / "index.html")


def test_stale_temporary_files_of_dead_writers_are_removed(work, capsys) -> None:
    out = work / "out"
    dead = [out / ".index.html.tmp",  # the old shared name, no writer in it
            out / "alpha" / ".manifest.json.999999999.abc123.tmp",
            out / "gamma" / "vtu" / ".x.vtu.999999999.q_1.tmp"]
    alive = out / "alpha" / f".faces-cells.csv.{os.getpid()}.zz.tmp"  # this process: still writing
    for p in [*dead, alive]:
        p.write_text("half a")
    assert _study(["study", "delta.toml", "--out", "out"], capsys)[0] == 0
    assert not [p for p in dead if p.exists()] and alive.exists()
    tally("report files", "accepted")


def test_a_dead_holder_does_not_keep_the_index_lock(work, capsys) -> None:
    """A process that took the index lock and was killed (SIGKILL) before releasing it: the next study writes
    its index at once."""
    pid = os.fork()
    if pid == 0:  # the child takes the lock and dies holding it
        with files.exclusive(work / "out" / ".index.lock"):
            os.kill(os.getpid(), signal.SIGKILL)
        os._exit(1)
    assert os.waitpid(pid, 0)[1] & 0x7F == signal.SIGKILL
    t0 = time.perf_counter()
    assert _study(["study", "delta.toml", "--out", "out"], capsys)[0] == 0
    assert time.perf_counter() - t0 < 30 and "id='delta'" in (work / "out" / "index.html").read_text()
    tally("report files", "accepted")


# ----------------------------------------------------------------------------- family 7: concurrency
# The driver: one process that first runs every study once, one after the other, into serial/ (the reference
# tables, and the warm-up: the imports and the lazy set-up of the solvers and matplotlib are paid once, not by
# each of 34 rounds on 2 loaded cores), then forks one lane per study and each lane one process per round
# (`pcverify study NAME --out shared --json`, stdout and stderr kept).  Prints {"serial": [...], "runs": [...]}.
DRIVER = r"""
import contextlib, io, json, os, sys, traceback
from pathlib import Path
from pcverify.harness.cli import main
from pcverify.harness.report.write import write_index

def forked(argv, log):
    pid = os.fork()
    if pid == 0:
        os.dup2(os.open(log + ".out", os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 1)
        os.dup2(os.open(log + ".err", os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 2)
        try:
            code = main(argv)
        except BaseException:
            traceback.print_exc()
            code = 99
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])
    return {"code": code, "out": Path(log + ".out").read_text(), "err": Path(log + ".err").read_text()}

lanes = json.loads(sys.argv[1])
serial = []
for study in dict.fromkeys(s for s, _ in lanes):
    with contextlib.redirect_stdout(io.StringIO()) as text:
        code = main(["study", study, "--out", "serial", "--json"])
    serial.append({"code": code, "out": text.getvalue()})
pids = []
for k, (study, rounds) in enumerate(lanes):
    pid = os.fork()
    if pid == 0:
        runs = [forked(["study", study, "--out", "shared", "--json"], f"log-{k}-{r}") for r in range(rounds)]
        Path(f"lane-{k}.json").write_text(json.dumps(runs))
        os._exit(0)
    pids.append(pid)
codes = [os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) for pid in pids]
runs = [run for k in range(len(lanes)) for run in json.loads(Path(f"lane-{k}.json").read_text())]
print(json.dumps({"lanes": codes, "serial": serial, "runs": runs}))
"""


def _timing_free(folder: Path) -> dict[str, pd.DataFrame]:
    out = {}
    for path in sorted(folder.glob("*.csv")):
        df = pd.read_csv(path)
        # clocks, and what a run records of itself: whether its worker was cold, its timed pass
        own = ("wall_s", "timing", "cold", "repeats", "run", "machine", "started")
        out[path.name] = df.drop(columns=[c for c in df.columns if c.endswith("_s") or c in own])
    return out


WAITED = "pcverify: waiting for another process: cell lock "  # said once a wait lasts 10 s: the machine's load


def test_concurrent_studies_on_one_out(tmp_path) -> None:
    """4 different studies x 8 rounds, each round a process of its own, the 4 lanes in parallel on one --out,
    together with 2 copies of a 6-cell study started at the same moment (their cells overlap beta's and
    delta's).  Every process exits 0 without a warning (saying that it waits for another process's cell is
    not one: it is said when the wait lasts 10 s, which on a busy machine it may); the cells computed add up
    to the distinct cells (none computed twice); every study's tables equal a serial run's; no temporary or
    lock file is left."""
    _write_studies(tmp_path)
    lanes = [("alpha.toml", 8), ("beta.toml", 8), ("gamma.toml", 8), ("delta.toml", 8), ("twin.toml", 1),
             ("twin.toml", 1)]
    run = subprocess.run([sys.executable, "-c", DRIVER, json.dumps(lanes)], cwd=tmp_path, env=ENV,
                         capture_output=True, text=True, timeout=600, check=False)
    assert run.returncode == 0, run.stderr[-1500:]
    doc = json.loads(run.stdout)
    assert doc["lanes"] == [0] * len(lanes) and len(doc["runs"]) == 34
    assert [s["code"] for s in doc["serial"]] == [0] * len(STUDIES)
    failed = [r["err"][-1500:] for r in doc["runs"] if r["code"] != 0]
    assert not failed, failed
    said = [line for r in doc["runs"] for line in r["err"].splitlines() if line.strip()]
    assert not [line for line in said if not line.startswith(WAITED)], said  # not even a warning
    summaries = [json.loads(r["out"])[0] for r in doc["runs"]]
    assert all(s["failed"] == 0 and s["corrupt"] == 0 and s["done"] + s["cached"] == s["cells"] for s in summaries)
    entries = len(list((tmp_path / "shared" / "cache").glob("*.json")))
    assert sum(s["done"] for s in summaries) == entries, [(s["study"], s["done"]) for s in summaries]
    assert sum(json.loads(s["out"])[0]["done"] for s in doc["serial"]) == entries  # the same distinct cells
    for name in STUDIES:
        shared, alone = _timing_free(tmp_path / "shared" / name), _timing_free(tmp_path / "serial" / name)
        assert shared.keys() == alone.keys() and shared
        for table in alone:
            pd.testing.assert_frame_equal(shared[table], alone[table], check_exact=True)
    index = (tmp_path / "shared" / "index.html").read_text()
    assert all(f"id='{name}'" in index for name in STUDIES) and index.endswith("</html>")
    assert json.loads((tmp_path / "shared" / "verdicts.json").read_text())
    assert not list((tmp_path / "shared").rglob("*.tmp")) and not list((tmp_path / "shared").rglob("cache/*.lock"))
    tally("concurrency", "accepted")


def test_zz_reports_tally() -> None:
    # report files: 12 garbage manifests, 40 fuzzed manifests (max_examples), 17 garbage benchmark saves,
    # 4 garbage verdicts files, 1 manifest through the command line, 1 atomic write, 1 full disk, 2 stale locks
    check_tally({"report files": 78, "embedded paths": 11, "concurrency": 1})
