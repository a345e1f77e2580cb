"""Particle solvers: one package per particle model (macromolecule, mca)."""
