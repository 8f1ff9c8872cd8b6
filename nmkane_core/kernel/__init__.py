"""From a model to machine code: kernel terms → generated source → numba, cached on disk;
the compiled loops' interface, and the compiled forms of a system's visuals and events."""
