"""The macromolecule model for large lattices (up to ~10^6 particles on a few cores): a Verlet list with
offset groups (`neighbours`), the race-free parallel kernel (`kernel`), K replicas with their own damping
and drive in one call (`ensemble`), and LAMMPS running the same model as a peer (`lammps_peer`).  Same pair
force (`..force`), fix kinds and status codes (`..codes`) as the solver's fixed-pair-list kernels."""
