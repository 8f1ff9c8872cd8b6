"""The built-in systems, defined through the public API (nothing special-cased):
the paper's two examples.  :mod:`nmkane_core.registry` registers :data:`BUILTIN`."""

from . import appell_hamel, sliding_particle

BUILTIN = {
    "appell-hamel": appell_hamel.appell_hamel,
    "sliding-particle": sliding_particle.sliding_particle,
}
