"""One browser's camera: framing a system in the part of the page the panel leaves free,
and following it.

Two ways of looking, chosen by the *Camera follows* box:

* **fixed** — the whole motion of the run (every path travelled, fixed surfaces) framed
  once (:meth:`CameraPlan.whole`); this is *Fit view*, and what the box unticked shows;
* **following** — the system's bodies at the shown time framed, and the camera then
  *translates* with them (never turns with a body: a spin or a heading change stays
  visible); the viewer's own orbit and zoom are kept.

A system's first view (and *Reset view*) is fixed when its whole motion is not much
larger than the system itself, following otherwise.  Both are seen from the side the
system declares (``Visuals.view``) and placed left of the control panel, which covers
the right of the canvas (:data:`PANEL_PX`).

The offset camera − target is learnt from the browser's camera reports: viser's
server-side camera state can be overwritten by a report the browser sent before it
received our last pose (observed: a reset view undone a frame later), so reports are
ignored after a reset until one shows the preset (see :meth:`CameraRig.on_report`).
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .fastpath import follow_camera

CATCH_UP_S = 15.0  # how long reports that do not show our preset are taken as stale (a slow browser)
PANEL_PX = 420.0  # the control panel (viser's "large" width) and its margin, at the right of the canvas
FOV = 1.309  # viser's default vertical field of view (75°)
DIRECTION = (0.55, -0.75, 0.5)  # seen from front-right and above unless the system says otherwise
MARGIN = 1.15  # the framed box takes at most 1/MARGIN of the view's height and of the free width


@dataclass(frozen=True)
class Viewport:
    """The canvas as the browser reported it (pixels, vertical field of view)."""

    width: float = 1400.0
    height: float = 900.0
    fov: float = FOV

    @property
    def free_width(self) -> float:
        """The width left of the panel (at least a third of the canvas)."""
        return max(self.width - PANEL_PX, self.width / 3)


def frame(bounds, direction=None, viewport: Viewport | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(look_at, position) showing a box ``bounds`` = (lowest, highest corner) whole in the
    free part of the canvas: seen from ``direction`` (from the box to the camera), just far
    enough for each of the box's corners to be inside the view's height and the free width
    (with a margin), and turned so that the box sits in the middle of the free part (left of
    the panel)."""
    vp = viewport or Viewport()
    lo, hi = (np.asarray(b, float) for b in bounds)
    centre = (lo + hi) / 2
    half = np.maximum((hi - lo) / 2, 0.15)  # a point or a flat box still gets a view
    d = np.array(DIRECTION if direction is None else direction, float)
    d /= np.linalg.norm(d)
    right = np.cross(-d, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9:  # looking straight down
        right = np.array([1.0, 0.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, -d)
    tan = math.tan(vp.fov / 2)  # half the view's height at distance 1
    panel = PANEL_PX if vp.free_width > vp.width / 3 else 0.0
    c = -(panel / 2) / (vp.height / 2) * tan  # the free part's middle, left of the view's axis (x/z)
    t_w = (vp.free_width / 2) / (vp.height / 2) * tan / MARGIN  # half the free width (x/z)
    t_h = tan / MARGIN
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
    # the camera at distance dist along d from the box's centre, turned so that the centre is seen
    # at x/z = c; a corner p (from the centre) at depth dist − p·d is in the free part when
    # |p·right + c p·d| ≤ t_w (dist − p·d) and |p·up| ≤ t_h (dist − p·d)
    along = corners @ d
    need_x = np.abs(corners @ right + c * along) / t_w
    need_y = np.abs(corners @ up) / t_h
    dist = float(np.max(along + np.maximum(need_x, need_y)))
    look_at = centre - right * c * dist  # the centre then sits at x/z = c
    return look_at, look_at + d * dist


@dataclass
class CameraPlan:
    """How a view's installed run is looked at (see the module docstring)."""

    whole: tuple[np.ndarray, np.ndarray]  # (look_at, position): the whole motion, fixed
    offset: np.ndarray  # following: camera − target
    shift: np.ndarray  # following: target − the bodies' centre
    follows: bool  # the first view follows (the whole motion is much larger than the system)


class CameraRig:
    """Aims ``client.camera`` (None: no camera, e.g. a test's shared server).

    ``alive()`` says whether the browser is still connected: nothing is sent to one that left."""

    def __init__(self, client, alive: Callable[[], bool]):
        self.client, self.alive = client, alive
        self.offset: np.ndarray | None = None  # camera − target while following
        self.reset_at = 0.0
        self.placed: tuple[np.ndarray, np.ndarray] | None = None  # the last (look_at, position) set

    def viewport(self) -> Viewport:
        """The browser's canvas (a default one until it has reported)."""
        cam = getattr(self.client, "camera", None)
        if cam is None:
            return Viewport()
        try:
            w, h, fov = float(cam.image_width), float(cam.image_height), float(cam.fov)
        except (AttributeError, AssertionError, TypeError, ValueError):  # not reported yet
            return Viewport()
        if not (w > 0 and h > 0 and 0 < fov < math.pi):
            return Viewport()
        return Viewport(w, h, fov)

    def place(self, look_at: np.ndarray, position: np.ndarray, following: bool) -> None:
        """Put the camera at ``position`` looking at ``look_at`` (a reset: later reports are
        checked against it); ``following``: the offset is then kept while following."""
        self.placed = (np.asarray(look_at, float), np.asarray(position, float))
        self.reset_at = time.monotonic()
        self.offset = self.placed[1] - self.placed[0] if following else None
        if self.client is None or not self.alive():
            return
        cam = self.client.camera
        with contextlib.suppress(AssertionError, ValueError):  # no camera message from the browser yet
            cam.position = position  # (moves look_at along: set it after)
            cam.look_at = look_at

    def follow(self, target: np.ndarray) -> None:
        """Every frame while following: the same translation, the viewer's orbit kept."""
        if self.offset is None or self.client is None or not self.alive():
            return
        with contextlib.suppress(AssertionError, ValueError):  # no camera message from the browser yet
            # the same two messages as the setters, without viser's orientation math
            follow_camera(self.client.camera, target + self.offset, target)

    def on_report(self, cam) -> None:
        """The browser reported its camera (it does when the viewer moves it): after it has
        caught up with our last preset, a changed offset is the viewer's own orbit or zoom,
        which following keeps."""
        try:
            offset = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
        except AssertionError:
            return
        if not np.all(np.isfinite(offset)) or np.linalg.norm(offset) < 1e-6 or self.placed is None:
            return
        ours = self.placed[1] - self.placed[0]
        if self.reset_at:  # waiting for the browser to show our preset
            caught_up = np.linalg.norm(offset - ours) <= 1e-3 * (1 + np.linalg.norm(ours))
            if not caught_up and time.monotonic() - self.reset_at < CATCH_UP_S:
                return  # a report sent before our preset arrived
            self.reset_at = 0.0
        if self.offset is not None:
            self.offset = offset
