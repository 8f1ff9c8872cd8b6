"""One browser's camera: a view's preset, or following a target while keeping the viewer's
own orbit and zoom.

The offset camera − target is kept here, learnt from the browser's camera reports:
viser's server-side camera state can be overwritten by a report the browser sent before
it received our last pose (observed: a reset view undone a frame later), so reports are
ignored after a reset until one shows the preset (see :meth:`CameraRig.on_report`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from .fastpath import follow_camera

CATCH_UP_S = 15.0  # how long reports that do not show our preset are taken as stale (a slow browser)


class CameraRig:
    """Aims ``client.camera`` (None: no camera, e.g. a test's shared server) for a system view.

    ``alive()`` says whether the browser is still connected: nothing is sent to one that left."""

    def __init__(self, client, alive: Callable[[], bool]):
        self.client, self.alive = client, alive
        self.offset = None  # camera − target while following
        self.reset_at = 0.0

    def aim(self, view, view_name: str, row: dict | None, reset: bool = False) -> None:
        """Point the camera: the view's preset (reset), or follow ``row`` (a state row)."""
        if self.client is None or not self.alive():
            return
        cam = self.client.camera
        try:
            if not view.follows:
                if reset and view.fixed_camera is not None:
                    self.reset_at = time.monotonic()
                    self.offset = None
                    look_at, position = view.fixed_camera
                    cam.position = position  # (moves look_at along: set it after)
                    cam.look_at = look_at
                return
            row = view.rest_row() if row is None else row
            target = view.camera_target(row, view_name)
            if reset:
                self.reset_at = time.monotonic()
                self.offset = view.camera_offset(row, view_name)
            if self.offset is None:
                return
            if reset:
                cam.position = target + self.offset  # moves look_at along by the same amount
                cam.look_at = target
            else:  # every frame while following: the same two messages, without viser's orientation math
                follow_camera(cam, target + self.offset, target)
        except (AssertionError, ValueError):  # no camera message from the browser yet
            pass

    def on_report(self, view, cam) -> None:
        """The browser reported its camera: after it has caught up with our last preset, a
        changed offset is the viewer's own orbit or zoom, which following then keeps."""
        if not view.follows:
            return
        try:
            offset = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
        except AssertionError:
            return
        if not np.all(np.isfinite(offset)) or np.linalg.norm(offset) < 1e-6:
            return
        ours = self.offset
        if self.reset_at:  # waiting for the browser to show our preset
            caught_up = ours is not None and np.linalg.norm(offset - ours) <= 1e-3 * (1 + np.linalg.norm(ours))
            if not caught_up and time.monotonic() - self.reset_at < CATCH_UP_S:
                return  # a report sent before our preset arrived
            self.reset_at = 0.0
        self.offset = offset
