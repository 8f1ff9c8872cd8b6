"""A run from settings to result: the plan (settings checked and resolved), initial
states, simulate, the Run result, events, and the registry of systems (built-in and plug-ins)."""
