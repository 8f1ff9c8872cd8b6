"""From a model to machine code: kernel terms → the model's C functions (cached on disk) run by
the compiled core (built once per machine); the loops' interface, and the compiled forms of a
system's visuals and events."""
