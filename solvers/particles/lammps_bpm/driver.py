"""One LAMMPS instance holding a Lattice: a data file written with numpy, bond_style bpm/spring (central
springs, F = k (r - r0), no smoothing, no damping), no pair forces.  LAMMPS errors raise `LammpsError` carrying
LAMMPS's own message."""

from __future__ import annotations

import os
import tempfile
import time
from typing import Any

import numpy as np

from .lattice import Lattice
from .loader import missing_styles, new_instance

STYLES = {"bond": ("bpm/spring",), "pair": ("zero",), "command": ("dynamical_matrix",)}
MARGIN = 4.0  # box margin around the bar, in spacings (fracture opens the bar by far less)


class LammpsError(RuntimeError):
    """A LAMMPS command failed; the message is LAMMPS's last error line."""


def last_line(err: BaseException) -> str:
    """The first line of a LAMMPS exception's text (its "ERROR: ..." line)."""
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__


class Bpm:
    """A LAMMPS run of `lat` with breaking strains `eps_c` per spring (inf: never breaks)."""

    def __init__(self, lat: Lattice, eps_c: np.ndarray | None = None) -> None:
        self.lat = lat
        self.cpu_s = 0.0
        self.wall_s = 0.0
        self.lmp = new_instance()
        try:
            missing = missing_styles(self.lmp, STYLES)
            if missing:
                raise LammpsError(f"this LAMMPS build lacks {', '.join(missing)}")
            self._tmp = tempfile.TemporaryDirectory(prefix="pcverify-bpm-")
            breaking = eps_c is not None and bool(np.isfinite(eps_c).any())
            eps = np.full(lat.i.size, 1e3) if eps_c is None else np.where(np.isfinite(eps_c), eps_c, 1e3)
            combos, self.bond_type = np.unique(np.column_stack([lat.k, eps]), axis=0, return_inverse=True)
            self.bond_type = self.bond_type.ravel() + 1
            masses, self.atom_type = np.unique(lat.mass, return_inverse=True)
            self.atom_type = self.atom_type.ravel() + 1
            data = os.path.join(self._tmp.name, "bar.data")
            self._write_data(data, masses)
            self.commands([
                "units si", "atom_style bond", "atom_modify map array sort 0 0", "boundary f f f",
                "special_bonds lj 0 1 1 coul 1 1 1", "newton on off",
                f"read_data {data}",
                f"bond_style bpm/spring break {'yes' if breaking else 'no'} smooth no",
                *[f"bond_coeff {t + 1} {c[0]:.17g} {c[1]:.17g} 0.0" for t, c in enumerate(combos)],
                f"pair_style zero {1.6 * lat.spacing:.17g} nocoeff", "pair_coeff * *",
                f"neighbor {0.3 * lat.spacing:.17g} bin", "neigh_modify every 1 delay 0 check yes",
                "comm_modify vel yes",
            ])
        except BaseException:
            self.close()
            raise

    def _write_data(self, path: str, masses: np.ndarray) -> None:
        lat = self.lat
        lo = lat.positions.min(axis=0) - MARGIN * lat.spacing
        hi = lat.positions.max(axis=0) + MARGIN * lat.spacing
        head = [f"pcverify bar lattice\n\n{lat.size} atoms\n{lat.i.size} bonds\n{masses.size} atom types\n"
                f"{int(self.bond_type.max())} bond types\n"]
        head += [f"{lo[d]:.17g} {hi[d]:.17g} {c}lo {c}hi\n" for d, c in enumerate("xyz")]
        head.append("\nMasses\n\n" + "".join(f"{t + 1} {m:.17g}\n" for t, m in enumerate(masses)))
        with open(path, "w") as fh:
            fh.write("".join(head) + "\nAtoms # bond\n\n")
            ids = np.arange(1, lat.size + 1)
            np.savetxt(fh, np.column_stack([ids, np.ones(lat.size), self.atom_type, lat.positions]),
                       fmt=["%d", "%d", "%d", "%.17g", "%.17g", "%.17g"])
            fh.write("\nBonds\n\n")
            np.savetxt(fh, np.column_stack([np.arange(1, lat.i.size + 1), self.bond_type, lat.i + 1, lat.j + 1]),
                       fmt="%d")

    def commands(self, lines: list[str]) -> None:
        """Run LAMMPS commands; LammpsError with LAMMPS's error line if one fails."""
        for line in lines:
            try:
                self.lmp.command(line)
            except Exception as err:  # noqa: BLE001 - lammps raises a bare Exception with its error text
                raise LammpsError(f"LAMMPS: {last_line(err)} (command: {line})") from None

    def timed(self, lines: list[str]) -> None:
        """`commands`, its wall and CPU time added to the run's cost."""
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            self.commands(lines)
        finally:
            self.wall_s += time.perf_counter() - t0
            self.cpu_s += time.process_time() - c0

    def group(self, name: str, nodes: np.ndarray) -> None:
        """A LAMMPS group of the given node indices (an empty group if none)."""
        ids = " ".join(str(int(v) + 1) for v in nodes)
        self.commands([f"group {name} id {ids}" if nodes.size else f"group {name} empty"])

    def positions(self) -> np.ndarray:
        return np.ctypeslib.as_array(self.lmp.gather_atoms("x", 1, 3)).reshape(self.lat.size, 3).copy()

    def forces(self) -> np.ndarray:
        return np.ctypeslib.as_array(self.lmp.gather_atoms("f", 1, 3)).reshape(self.lat.size, 3).copy()

    def fix_vector(self, fix: str, index: int) -> float:
        """Element `index` of a fix's global vector (fix setforce: the group's force before it was set)."""
        return float(self.lmp.extract_fix(fix, 0, 1, index))

    def bonds_left(self) -> int:
        """Bonds not broken: half the sum of each atom's count of unbroken bonds (compute nbond/atom)."""
        self.commands(["compute nb all nbond/atom", "compute nbsum all reduce sum c_nb", "run 0 post no"])
        total = float(self.lmp.extract_compute("nbsum", 0, 0))
        self.commands(["uncompute nbsum", "uncompute nb"])
        return int(round(total / 2))

    @property
    def version(self) -> int:
        return int(self.lmp.version())

    def close(self) -> None:
        lmp = getattr(self, "lmp", None)
        if lmp is not None:
            lmp.close()
            self.lmp = None
        tmp = getattr(self, "_tmp", None)
        if tmp is not None:
            tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> Bpm:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()
