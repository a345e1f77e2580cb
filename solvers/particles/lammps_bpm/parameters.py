"""The lammps-bpm solver's parameters, declared apart from it so that the command line checks them without
importing LAMMPS."""

from __future__ import annotations

from pcverify.scene import Param

BREAK_SCALES = ("lattice", "material", "equal")

PARAMETERS: tuple[Param, ...] = (
    Param("cfl", 0.5, "", "fracture: time step as a fraction of 2/omega_max (Gershgorin bound of the spring "
          "network)", low=0.0, high=1.0, low_open=True),
    Param("ftol", 1e-9, "", "static scenes: LAMMPS minimize force tolerance in units of E |strain| a^2",
          low=0.0, high=1e-2, low_open=True),
    Param("max_iterations", 100_000, "", "static scenes: largest number of minimizer iterations", low=1, high=1e8,
          kind=int),
    Param("fd_delta", 1e-6, "", "modes: finite-difference displacement of LAMMPS's dynamical_matrix in units of a",
          low=1e-12, high=1e-2),
    Param("diagonal_break", "lattice", "", "fracture: breaking strain of the face diagonals relative to the axis "
          "bonds' sigma_t / E: lattice = (1 - 1/4)/2 (their strain in uniaxial tension of this lattice, nu = 1/4), "
          "material = (1 - nu)/2 with the scene's nu, equal = 1 (no scaling)", choices=BREAK_SCALES, kind=str),
)
