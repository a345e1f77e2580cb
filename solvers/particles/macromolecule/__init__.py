"""Arinchev's macromolecule model: heat conduction as forced vibration of a seven-root particle lattice.

LAMMPS split: `force` (the pair style), `fixes` (held, driven, bath particles), `computes` (measurements),
`kernel` (the one integrator: inputs, pair pass, step); `lattice`, `codes`, `simulate` (runs the kernel;
hotness, energy balance, status), `modal`, `setup`, `probe`, `elastic_modes` and `solver` (the glue).
"""
