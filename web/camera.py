"""One browser's camera: framing a system in the part of the page the panel leaves free,
and following it.

What is framed is the **mechanism**: its parts (the solids on its frames, the balls and
line segments that move with the state — a load on its thread, a bar), not the paths their
points trace (:meth:`web.declared.DeclaredScene.parts_at`).  Two ways of looking, chosen by
the *Camera follows* box:

* **fixed** — the camera stays where it was put;
* **following** — the camera *translates* with the mechanism (never turns with a body: a
  spin or a heading change stays visible); the viewer's own orbit and zoom are kept.

A system's **first view** (and *Reset view*) is seen from the side the system declares
(``Visuals.view``).  It is fixed on the whole motion of the parts
(:attr:`CameraPlan.motion`) unless that would show the mechanism at less than
1/:data:`FIXED_UP_TO` of the size a following camera shows it; then it follows, framing
everything the parts do around the point it follows over the whole run
(:meth:`~web.declared.DeclaredScene.parts_envelope`: a falling load, a heading that turns),
so that they stay in view at every time.  **Fit view** frames the mechanism as it is at
the shown time, from the side the viewer looks from now, and keeps following or not as the
box says.  Every view is placed left of the control panel, which covers the right of the
canvas (:data:`PANEL_PX`).

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
from .labels import View

CATCH_UP_S = 15.0  # how long reports that do not show our preset are taken as stale (a slow browser)
PANEL_PX = 420.0  # the control panel (viser's "large" width) and its margin, at the right of the canvas
FOV = 1.309  # viser's default vertical field of view (75°)
DIRECTION = (0.55, -0.75, 0.5)  # seen from front-right and above unless the system says otherwise
MARGIN = 1.15  # the framed box takes at most 1/MARGIN of the view's height and of the free width
#: a first view is fixed on the whole motion unless that shows the mechanism at less than
#: 1/FIXED_UP_TO of the size a following camera shows it (a vehicle that travels, a load that
#: falls far): then it follows
FIXED_UP_TO = 1.6


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
    half = (hi - lo) / 2
    largest = float(np.max(half))
    # a flat box still gets depth (a tenth of its largest side: a 10 cm linkage is not framed as
    # 30 cm), a point a view of 15 cm
    half = np.maximum(half, 0.1 * largest if largest > 0 else 0.15)
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


def distance(view: tuple[np.ndarray, np.ndarray]) -> float:
    """How far a view's camera is from what it looks at (a view from :func:`frame`)."""
    look_at, position = view
    return float(np.linalg.norm(np.asarray(position, float) - np.asarray(look_at, float)))


def follows(motion: tuple[np.ndarray, np.ndarray], envelope: tuple[np.ndarray, np.ndarray]) -> bool:
    """Whether a first view follows: the view of the whole motion (fixed) is more than
    :data:`FIXED_UP_TO` times as far away as the following view of the envelope."""
    return distance(motion) > FIXED_UP_TO * max(distance(envelope), 1e-9)


@dataclass
class CameraPlan:
    """How a view's installed run is looked at (see the module docstring)."""

    whole: tuple[np.ndarray, np.ndarray]  # (look_at, position): every path travelled (the exported file's view)
    motion: tuple[np.ndarray, np.ndarray]  # (look_at, position): the parts' whole motion (a fixed first view)
    offset: np.ndarray  # following: camera − target
    shift: np.ndarray  # following: target − the point followed
    follows: bool  # the first view follows (the fixed one would show the mechanism much smaller)


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
        return self._canvas() or Viewport()

    def _canvas(self) -> Viewport | None:
        """The canvas the browser reported, or None (no browser, or no report yet)."""
        cam = getattr(self.client, "camera", None)
        if cam is None:
            return None
        try:
            w, h, fov = float(cam.image_width), float(cam.image_height), float(cam.fov)
        except (AttributeError, AssertionError, TypeError, ValueError):  # not reported yet
            return None
        return Viewport(w, h, fov) if w > 0 and h > 0 and 0 < fov < math.pi else None

    def view(self) -> View | None:
        """Where the browser's camera is and what it sees (for :mod:`web.labels`), or None before
        it has reported its camera."""
        canvas = self._canvas() if self.alive() else None
        if canvas is None:
            return None
        cam = self.client.camera
        try:
            position, look_at = np.asarray(cam.position, float), np.asarray(cam.look_at, float)
            up = np.asarray(cam.up_direction, float)
        except (AttributeError, AssertionError, TypeError, ValueError):  # not reported yet
            return None
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(look_at))):
            return None
        return View(position, look_at, up, canvas.fov, canvas.width, canvas.height)

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

    def hold(self) -> None:
        """Stop following: the camera stays where it is."""
        self.offset = None

    def direction(self) -> np.ndarray | None:
        """The side the browser's camera looks from now (camera − look_at, unit), or None
        (no browser, or it has not reported its camera yet)."""
        cam = getattr(self.client, "camera", None)
        if cam is None:
            return None
        try:
            d = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
        except (AssertionError, AttributeError, TypeError, ValueError):
            return None
        n = float(np.linalg.norm(d))
        return d / n if np.all(np.isfinite(d)) and n > 1e-9 else None

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
