"""Analysis of any system at a state: accelerations, linearization, eigenvalue sweeps."""
