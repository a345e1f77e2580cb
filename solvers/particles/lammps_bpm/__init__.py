"""LAMMPS's bonded particle model (BPM) as a shipped solver: a central-spring lattice driven in-process."""
