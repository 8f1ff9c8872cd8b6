"""The page's *Export* button: the run on screen (with its compare ghosts) as the offline
page of :mod:`web.export`, offered to the browser as a download (viser's
``send_file_download``: the file goes over the page's websocket, nothing else is served)."""

from __future__ import annotations

import threading
import time

LABEL = "Export run (offline HTML)"
HINT = (
    "One HTML file that plays this run's 3D animation (with its ghosts) and shows its plots, "
    "without a server or a network: for a slide, an e-mail, a learning platform"
)


class ExportButton:
    """A button that exports ``app.traj`` (``app``: a :class:`~web.session.MechanismApp`:
    ``lock``, ``traj``, ``target`` and ``alive()``); one export at a time per page."""

    def __init__(self, gui, app):
        self.app = app
        self.button = gui.add_button(LABEL, hint=HINT)
        self.button.on_click(lambda _: self.export())
        self._busy = threading.Lock()
        self.last: tuple[str, int] | None = None  # (file name, bytes) of the last download sent

    def export(self) -> tuple[str, int] | None:
        """Export the shown run and send it (None when there is no run yet, or one is being
        exported)."""
        from .export import export_html

        with self.app.lock:
            traj = self.app.traj
        if traj is None or not self._busy.acquire(blocking=False):
            return None
        self.button.disabled, self.button.label = True, "Exporting …"
        try:
            data = export_html(traj).encode("utf-8")
        finally:
            self.button.disabled, self.button.label = False, LABEL
            self._busy.release()
        name = f"{traj.kind}-{time.strftime('%Y%m%d-%H%M%S')}.html"
        if self.app.alive():
            self.app.target.send_file_download(name, data, save_immediately=True)
        self.last = (name, len(data))
        return self.last
