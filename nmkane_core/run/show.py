"""``nmkane_core.show(system, settings)``: simulate and show the run inline in Jupyter, by
the installed viewer (:mod:`nmkane_core.run.viewer`; ``run.show()`` shows a run already made)."""

from __future__ import annotations

from collections.abc import Mapping

from ..errors import InputError
from .viewer import show_run

__all__ = ["show"]


def show(system: str, settings: Mapping | None = None, **options):
    """Simulate ``system`` with ``settings`` (the run settings as a mapping, without or with
    the same ``system``; omitted fields take the system's defaults) and show the run:
    ``nmkane_core.show(NAME, {"t_final": 5})`` as the last line of a notebook cell."""
    from .simulate import simulate

    settings = dict(settings or {})
    if settings.get("system", system) != system:
        raise InputError("system", settings["system"], f"the system shown: {system!r} (or leave it out)")
    return show_run(simulate({**settings, "system": system}, progress=False), **options)
