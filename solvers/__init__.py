"""Everything that turns a scene into a solution: the solver protocol, the registry, the continuum
solvers (FiPy, scikit-fem) and the particle models (macromolecule, movable cellular automata)."""
