"""The built-in systems, defined through the public API (nothing special-cased):
the paper's two examples.  :mod:`nmkane_core.registry` registers :data:`BUILTIN`."""

from . import appell_hamel, sliding_particle, whipple_bicycle

BUILTIN = {
    "appell-hamel": appell_hamel.appell_hamel,
    "sliding-particle": sliding_particle.sliding_particle,
    "whipple-bicycle": whipple_bicycle.whipple_bicycle,
}
