"""Arinchev's macromolecule model: heat conduction as forced vibration of a seven-root particle lattice."""
