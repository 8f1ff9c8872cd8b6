"""The symbolic side: a model described with sympy, the paper's derivation (steps 1–5),
the expressions a numeric kernel evaluates and the plain numpy reference."""
