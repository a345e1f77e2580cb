"""Arinchev's macromolecule model: heat conduction as forced vibration of a seven-root particle lattice.

Pieces: `lattice` (nodes, masses, fixed pair list), `force` (the one pair force), `fixes` (what each
particle's motion is), `codes` (fix kinds, status codes and output slots every kernel shares), the
fixed-pair-list kernel family (`kernel_state`: the structures they take; `kernel_reference`,
`kernel_fast`; `kernels`: the table they are chosen from; `computes`: their shared checks), `simulate`
(runs a kernel, measures hotness, energy balance, hops, status), `modal`, `setup`, `probe`, `solver`,
`elastic_modes`, and `large_n` (the large-lattice kernel, its neighbour lists, ensembles, the LAMMPS peer).
"""
