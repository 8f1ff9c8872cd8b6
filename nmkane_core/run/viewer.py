"""The viewer that shows a run inline in Jupyter (``run.show()``, :func:`nmkane_core.show`).

The core draws nothing itself and imports no face: the viewer is whatever installed package
declares itself in the entry-point group ``nmkane.show`` — the web app does
(``web = "web.export:show"``: its offline export, the 3D animation with its playback bar and
the plots, in an iframe whose ``srcdoc`` is the whole page, so nothing is fetched).
"""

from __future__ import annotations

from importlib.metadata import entry_points

from ..errors import NmkaneError

__all__ = ["ENTRY_POINT_GROUP", "show_run", "viewer"]

ENTRY_POINT_GROUP = "nmkane.show"


def viewer():
    """The installed viewer (the ``web`` entry of ``nmkane.show`` first, else any): a
    function ``(run, **options) -> displayable``."""
    found = sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda ep: (ep.name != "web", ep.name))
    if not found:
        raise NmkaneError(
            f"show() needs a viewer: none is installed in the entry-point group {ENTRY_POINT_GROUP!r} "
            "(the web app has one: pip install 'nmkane[web]')"
        )
    try:
        return found[0].load()
    except ImportError as e:
        raise NmkaneError(f"show(): the viewer {found[0].value!r} cannot be imported ({e})") from None


def show_run(run, **options):
    """``run`` shown by the installed viewer; ``options`` are the viewer's (the web app's:
    ``height`` in pixels)."""
    return viewer()(run, **options)
