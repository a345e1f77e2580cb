"""The movable cellular automaton (MCA) method of Psakhie et al.: elasticity, fracture, modes and heat."""
