"""The paper's two examples, defined through the public API (nothing special-cased)."""

from . import appell_hamel, sliding_particle  # noqa: F401  (register on import)
