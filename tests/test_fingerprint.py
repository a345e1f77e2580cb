"""Nothing stale survives a source edit: the code fingerprint covers the source closure of a solver (across
packages; installed third-party libraries by name and version), the study cache recomputes exactly the
cells whose closure changed, and numba's on-disk cache never serves code compiled from an older source of
any module the jitted function reaches (a helper module, MCA's friction law)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from lint_imports import REPO, installed_layout

from pcverify import numba_guard
from pcverify.fingerprint import module_fingerprint, source_closure

ENV = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MPLBACKEND": "Agg"}


def _write(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text))


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new))


def _python(code: str, env: dict[str, str], cwd: Path) -> str:
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=cwd, check=False)
    assert out.returncode == 0, out.stderr[-3000:]
    return out.stdout


# ----------------------------------------------------------------------------- numba: no stale compiled code
KERNEL = {
    "kern/__init__.py": "",
    "kern/kernel.py": """
        from numba import njit

        from . import helper


        @njit(cache=True)
        def run(x):
            return helper.scale(x)
        """,
    "kern/helper.py": """
        from numba import njit


        @njit
        def scale(x):
            return 2.0 * x
        """,
}


def test_an_edited_helper_recompiles_the_cached_kernel_that_calls_it(tmp_path) -> None:
    """numba's own cache checks only kernel.py; after helper.py changes, a new process with the same
    NUMBA_CACHE_DIR must run the new helper, not the machine code compiled from the old one."""
    _write(tmp_path, KERNEL)
    env = {**ENV, "PYTHONPATH": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    code = "import pcverify\nfrom kern import kernel\nprint(kernel.run(1.0))"
    assert float(_python(code, env, tmp_path)) == 2.0
    assert float(_python(code, env, tmp_path)) == 2.0  # from the cache
    assert any((tmp_path / "numba").rglob("*.nbi"))
    _edit(tmp_path / "kern" / "helper.py", "2.0 * x", "3.0 * x")
    assert float(_python(code, env, tmp_path)) == 3.0


def test_numba_is_guarded_lazily_and_an_unknown_numba_fails_loudly(tmp_path) -> None:
    """`import pcverify` does not import numba; when numba's caching module loads, every locator class is
    wrapped (once, however often it is asked); a numba without the locator list is an ImportError."""
    code = textwrap.dedent("""
        import sys
        import pcverify
        from pcverify import numba_guard
        assert "numba" not in sys.modules
        from numba.core import caching
        names = [c.__name__ for c in caching.CacheImpl._locator_classes]
        numba_guard.guard_numba_cache()
        numba_guard.guard(caching)
        assert [c.__name__ for c in caching.CacheImpl._locator_classes] == names
        print(" ".join(names))
        """)
    names = _python(code, ENV, tmp_path).split()
    assert names and all(n.startswith("ClosureStamped") and "ClosureStampedClosureStamped" not in n for n in names)
    with pytest.raises(ImportError, match="cannot guard numba's cache"):
        numba_guard.guard(type(sys)("numba_without_locators"))


@pytest.mark.slow
def test_an_edit_of_the_friction_law_reaches_a_cached_mca_run(tmp_path) -> None:
    """The case that was stale: mca/kernel.py's jitted step calls contact.py's friction law.  A copy of the
    product (installed layout, on PYTHONPATH ahead of the editable install) runs block-sliding; its dry
    friction is multiplied by 1.5; the rerun with the same NUMBA_CACHE_DIR measures mu_dr = 0.45, not 0.30."""
    src = installed_layout(REPO, tmp_path / "src")
    shutil.copytree(REPO / "harness" / "studies", src / "pcverify" / "harness" / "studies")
    env = {**ENV, "PYTHONPATH": str(src), "NUMBA_CACHE_DIR": str(tmp_path / "numba")}
    contact = src / "pcverify" / "solvers" / "particles" / "mca" / "contact.py"
    where = _python("import pcverify.solvers.particles.mca.contact as c\nprint(c.__file__)", env, tmp_path)
    assert Path(where.strip()) == contact

    def mu_dr() -> float:
        out = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "run", "block-sliding", "--solver", "mca",
                              "--n", "2", "--json"], capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
        assert out.returncode == 0, out.stderr[-3000:]
        return json.loads(out.stdout)["summary"]["mu_dr_mean"]

    assert mu_dr() == pytest.approx(0.3, rel=1e-4)
    _edit(contact, "dry = law.mu1 * (1.0 + rough)", "dry = 1.5 * law.mu1 * (1.0 + rough)")
    assert mu_dr() == pytest.approx(0.45, rel=1e-4)


# ----------------------------------------------------------------------------- the closure, across packages
SOLVER = '''
    """{doc}"""
    import numpy as np

    from pcverify import FaceTemperature, Param, Solution, effective_params

    SCALE = 1.0


    class {cls}:
        """The linear steady profile between two held z faces, times SCALE."""

        name = "{name}"
        kind = "continuum"
        parameters = (Param("scale", 1.0, "", "factor on the result", low=0.0, high=10.0),)

        def supports(self, scene):
            faces = {{c.face for c in scene.constraints if isinstance(c, FaceTemperature)}}
            ok = scene.physics == frozenset({{"conduction"}}) and faces == {{"z0", "zL"}}
            return ok, "" if ok else "two held z faces only"

        def solve(self, scene, resolution, samples=None, **params):
            p = effective_params(self, params)
            sets = scene.sample_sets(resolution.n) if samples is None else samples
            out = {{k: {{"points": v, "values": SCALE * p["scale"] * (1.0 - v[:, 2] / scene.box.length)}}
                   for k, v in sets.items()}}
            nodes = out["nodes"]["values"]
            return Solution(scene=scene.name, solver=self.name, params=p,
                            resolution={{"n": resolution.n, "refine": resolution.refine}}, samples=out,
                            unknowns=len(nodes), wall_s=0.0, summary={{"bulk_median": float(np.median(nodes))}})
    '''

PACKAGES = {
    "corelib/__init__.py": '"""A core library: the solver a thin plugin wraps."""\n',
    "corelib/linear.py": SOLVER.format(doc="The core solver.", cls="CoreLinear", name="core-linear"),
    "thinplugin/__init__.py": "",
    "thinplugin/solver.py": '''
        """A thin plugin around corelib: its solver is corelib's under another name."""
        from corelib.linear import CoreLinear


        class ThinLinear(CoreLinear):
            """corelib's linear profile, as a plugin."""

            name = "thin-linear"
        ''',
    "otherplug/__init__.py": "",
    "otherplug/solver.py": SOLVER.format(doc="An unrelated plugin.", cls="OtherLinear", name="other-linear"),
}


def test_a_plugin_subclassing_another_package_follows_its_edits(tmp_path, monkeypatch) -> None:
    """thinplugin's solver subclasses corelib's: its fingerprint changes when corelib's code changes (not its
    docstrings), and covers corelib's package __init__; numpy enters by name and version, not by its files."""
    _write(tmp_path, PACKAGES)
    monkeypatch.syspath_prepend(str(tmp_path))
    closure = source_closure("thinplugin.solver")
    assert {"thinplugin", "thinplugin.solver", "corelib", "corelib.linear", "pcverify", "pcverify.scene"} <= set(
        closure)
    assert closure["dist:numpy"] == np.__version__ and not any(k.startswith("numpy") for k in closure)
    before = module_fingerprint("thinplugin.solver")
    other = module_fingerprint("otherplug.solver")
    _edit(tmp_path / "corelib" / "linear.py", '"""The core solver."""', '"""The core solver, documented."""')
    assert module_fingerprint("thinplugin.solver") == before
    _edit(tmp_path / "corelib" / "linear.py", "SCALE = 1.0", "SCALE = 1.1")
    assert module_fingerprint("thinplugin.solver") != before
    assert module_fingerprint("otherplug.solver") == other
    edited = module_fingerprint("thinplugin.solver")
    _edit(tmp_path / "corelib" / "__init__.py", 'wraps."""\n', 'wraps."""\nFLAG = 1\n')  # run before corelib.linear
    assert module_fingerprint("thinplugin.solver") != edited


def test_resolving_a_closure_imports_nothing(tmp_path, monkeypatch) -> None:
    """Finding the files of modules that are not imported must not import them or their parent packages
    (importlib.util.find_spec would run the parents' __init__.py)."""
    _write(tmp_path, {"quiet/__init__.py": "raise RuntimeError('quiet was imported')\n",
                      "quiet/sub/__init__.py": "",
                      "quiet/sub/leaf.py": "from .. import other\nfrom ..sub import sibling\n",
                      "quiet/sub/sibling.py": "X = 1\n", "quiet/other.py": "Y = 1\n"})
    monkeypatch.syspath_prepend(str(tmp_path))
    closure = source_closure("quiet.sub.leaf")
    assert {"quiet", "quiet.sub", "quiet.sub.leaf", "quiet.sub.sibling", "quiet.other"} <= set(closure)
    assert not [m for m in sys.modules if m.split(".")[0] == "quiet"]


def test_installed_pcverify_and_the_plugins_own_package_count_by_source(tmp_path) -> None:
    """In a site-packages folder (a non-editable install), pcverify and the solver's own package are still
    hashed by source; another distribution there counts by its name and version."""
    site = installed_layout(REPO, tmp_path / "lib" / "site-packages")
    _write(site, {"plugx/__init__.py": "", "plugx/solver.py": "import libx\nimport pcverify\n",
                  "libx/__init__.py": "VALUE = 1\n",
                  "plugx-1.0.dist-info/METADATA": "Metadata-Version: 2.1\nName: plugx\nVersion: 1.0\n",
                  "plugx-1.0.dist-info/top_level.txt": "plugx\n",
                  "libx-2.5.dist-info/METADATA": "Metadata-Version: 2.1\nName: libx\nVersion: 2.5\n",
                  "libx-2.5.dist-info/top_level.txt": "libx\n"})
    code = textwrap.dedent("""
        import json
        from pcverify.fingerprint import source_closure
        print(json.dumps([source_closure("plugx.solver"), source_closure("pcverify.solvers.particles.mca.solver")]))
        """)
    plugin, mca = json.loads(_python(code, {**ENV, "PYTHONPATH": str(site)}, tmp_path))
    assert {"plugx.solver", "pcverify", "pcverify.solvers.protocol"} <= set(plugin)
    assert plugin["dist:libx"] == "2.5" and "libx" not in plugin and "dist:plugx" not in plugin
    assert {"pcverify.solvers.particles.mca.contact", "pcverify.solvers.particles.mca.kernel"} <= set(mca)
    assert not [k for k in mca if k.startswith("dist:pcverify")]


# ----------------------------------------------------------------------------- the study cache
STUDY = """
name = "two-plugins"
plugins = ["thinplugin.solver", "otherplug.solver"]
[[group]]
id = "faces"
scene = "bar-heat-faces"
solvers = ["thin-linear", "other-linear"]
n = [2, 3]
"""


def test_exactly_the_cells_of_the_edited_code_recompute(tmp_path) -> None:
    """Two plugin solvers in two packages, one a thin subclass of corelib: an edit of corelib recomputes
    the thin plugin's cells only (with the new number), an edit of the other plugin its cells only, and a
    docstring edit nothing; nobody clears a cache."""
    _write(tmp_path, {**PACKAGES, "study.toml": STUDY})
    env = {**ENV, "PYTHONPATH": str(tmp_path)}

    def study() -> tuple[dict, pd.DataFrame]:
        out = subprocess.run([sys.executable, "-m", "pcverify.harness.cli", "study", "study.toml", "--out", "out",
                              "--json"], capture_output=True, text=True, env=env, cwd=tmp_path, check=False)
        assert out.returncode == 0, out.stderr[-3000:]
        cells = pd.read_csv(tmp_path / "out" / "two-plugins" / "faces-cells.csv")
        return json.loads(out.stdout)[0], cells.set_index(["solver", "n"])["err.nodes.linf"]

    first, errors = study()
    assert (first["done"], first["cached"], first["failed"]) == (4, 0, 0)
    assert (errors < 1e-12).all()
    _edit(tmp_path / "corelib" / "linear.py", "SCALE = 1.0", "SCALE = 1.1")
    core, errors = study()
    assert (core["done"], core["cached"]) == (2, 2)
    assert errors["thin-linear"].to_numpy() == pytest.approx(0.1, rel=1e-9)
    assert (errors["other-linear"] < 1e-12).all()
    _edit(tmp_path / "otherplug" / "solver.py", "SCALE = 1.0", "SCALE = 1.2")
    other, errors = study()
    assert (other["done"], other["cached"]) == (2, 2)
    assert errors["other-linear"].to_numpy() == pytest.approx(0.2, rel=1e-9)
    _edit(tmp_path / "corelib" / "linear.py", '"""The core solver."""', '"""The core solver, documented."""')
    again, _ = study()
    assert (again["done"], again["cached"]) == (0, 4)


COMPILED_ONCE = '''
import json, sys, time
import pcverify  # guards numba: the cache stamp and the compile lock
from numba import njit


@njit(cache=True)
def kernel(x):
    s = 0.0
    for i in range(x.shape[0]):
        for j in range(x.shape[0]):
            s += (x[i] - x[j]) ** 2 / (1.0 + abs(x[i] * x[j]))
    return s


if __name__ == "__main__":
    import numpy as np
    open(sys.argv[1], "w").close()  # started
    kernel(np.ones(3))
    stats = kernel.stats
    print(json.dumps({"hits": sum(stats.cache_hits.values()), "misses": sum(stats.cache_misses.values())}))
'''


def _kernel_process(tmp_path: Path, tag: str) -> subprocess.Popen:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba"), PYTHONPATH=str(tmp_path))
    return subprocess.Popen([sys.executable, str(tmp_path / "kern.py"), str(tmp_path / f"started-{tag}")], env=env,
                            stdout=subprocess.PIPE, text=True)


def _waiting_for(lock: Path) -> set[int]:
    """Pids of the processes blocked in flock(2) on the file `lock` (Linux's /proc/locks: the `->` lines)."""
    st = lock.stat()
    inode = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    pids = set()
    for line in Path("/proc/locks").read_text().splitlines():
        fields = line.split()
        if len(fields) > 6 and fields[1] == "->" and fields[2] == "FLOCK" and fields[6] == inode:
            pids.add(int(fields[5]))
    return pids


def test_a_kernel_is_compiled_once_while_another_process_waits_for_it(tmp_path) -> None:
    """Processes compiling the same cached function: while one holds the signature's lock the other waits,
    then loads what was saved (a cache hit) instead of compiling it a second time.  Two started together: one
    compiles, one loads, whichever is first.  That it waits is seen in the kernel's table of blocked locks, not
    inferred from its not finishing within seconds (which on a busy machine it would not do anyway)."""
    import fcntl

    (tmp_path / "kern.py").write_text(COMPILED_ONCE)
    first = _kernel_process(tmp_path, "a")
    assert json.loads(first.communicate(timeout=120)[0]) == {"hits": 0, "misses": 1}
    locks = list((tmp_path / "numba").rglob("*.lock"))
    assert len(locks) == 1 and locks[0].name.startswith("kern.kernel-")
    shutil.rmtree(tmp_path / "numba")
    locks[0].parent.mkdir(parents=True)
    with open(locks[0], "a") as held:  # another process compiling it
        fcntl.flock(held, fcntl.LOCK_EX)
        waiting = _kernel_process(tmp_path, "b")
        end = time.monotonic() + 120
        while waiting.pid not in _waiting_for(locks[0]):  # blocked on the lock
            assert waiting.poll() is None, "it compiled without waiting for the lock"
            assert time.monotonic() < end, "it did not come to wait for the lock in 120 s"
            time.sleep(0.05)
        assert waiting.poll() is None
    assert json.loads(waiting.communicate(timeout=120)[0]) == {"hits": 0, "misses": 1}  # nobody saved it
    shutil.rmtree(tmp_path / "numba")
    pair = [_kernel_process(tmp_path, tag) for tag in ("c", "d")]
    outcomes = sorted(json.dumps(json.loads(p.communicate(timeout=120)[0])) for p in pair)
    assert outcomes == [json.dumps({"hits": 0, "misses": 1}), json.dumps({"hits": 1, "misses": 0})]
