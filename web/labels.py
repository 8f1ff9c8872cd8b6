"""Labels that do not cover each other (issue 43, item 6): which corner of its text each 3D label
holds at its point, chosen in the browser's picture (pure numpy, no viser).

A label (a part's name, a force's magnitude at its arrow's tip) is drawn by viser at a fixed size
on the screen, one corner of its text at its point (its *anchor*).  Two labels whose points are
close on the screen (a load just under its pulleys, a thread's force at the load, seen from
far) covered each other when every label held its bottom-left corner.  :func:`choose` gives each
label, in order, the first of its corners and sides' middles (:data:`ANCHORS`) whose text box
meets no box placed before it, keeping a label's present anchor while that one is free (labels
do not hop from frame to frame), then moves the labels that still cover others to the anchor
that covers least.
:class:`LabelLayout` applies it to a browser's labels and camera each frame, sending only the
corners that change.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

#: the corners (and sides' middles) a label may hold at its point, in order of preference (the
#: first: its text above and right of the point)
ANCHORS = (
    "bottom-left",
    "top-left",
    "bottom-right",
    "top-right",
    "center-left",
    "center-right",
    "bottom-center",
    "top-center",
)
PASSES = 4  # rounds of moving a covering label to its least covering anchor
CHAR_PX = 6.0  # a label's width per character (viser 1.1's labels: 5.5 px, measured in Chromium)
PAD_PX = 10.0  # its background's padding, both sides together
HEIGHT_PX = 18.0  # its height
#: labels side by side closer than this are avoided where the anchors allow (two texts that touch
#: on one line read as one: "thread 9.24 Nload P"), after covering; one above the other they may
#: touch (lines of a list)
GAP_PX = 4.0
COVER_WEIGHT = 1000.0  # a pixel covered weighs as much as this many pixels of touching


@dataclass(frozen=True)
class View:
    """A browser's camera: where it is, what it looks at, its up, vertical field of view (rad)
    and canvas (px)."""

    position: np.ndarray
    look_at: np.ndarray
    up: np.ndarray
    fov: float
    width: float
    height: float

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Screen pixels (n, 2; x right, y down, the canvas' corner at 0, 0) of world points
        (n, 3), and which of them are in front of the camera."""
        f = np.asarray(self.look_at, float) - np.asarray(self.position, float)
        f /= max(float(np.linalg.norm(f)), 1e-12)
        right = np.cross(f, np.asarray(self.up, float))
        if np.linalg.norm(right) < 1e-9:  # looking along up
            right = np.cross(f, [1.0, 0.0, 0.0] if abs(f[0]) < 0.9 else [0.0, 1.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, f)
        d = np.asarray(points, float).reshape(-1, 3) - np.asarray(self.position, float)
        depth = d @ f
        scale = (self.height / 2) / (np.maximum(depth, 1e-9) * math.tan(self.fov / 2))
        xy = np.column_stack((self.width / 2 + (d @ right) * scale, self.height / 2 - (d @ up) * scale))
        return xy, depth > 1e-9


def seen_from(look_at, position, viewport) -> View:
    """The :class:`View` of a camera placed at ``position`` looking at ``look_at``, z up, on a
    canvas ``viewport`` (:class:`web.camera.Viewport`: width, height, fov)."""
    return View(
        np.asarray(position, float),
        np.asarray(look_at, float),
        np.array([0.0, 0.0, 1.0]),
        float(viewport.fov),
        float(viewport.width),
        float(viewport.height),
    )


def box(xy, text: str, anchor: str) -> tuple[float, float, float, float]:
    """(left, top, right, bottom) in pixels of a label of ``text`` holding ``anchor`` at ``xy``."""
    w, h = CHAR_PX * len(text) + PAD_PX, HEIGHT_PX
    x, y = float(xy[0]), float(xy[1])
    vertical, horizontal = anchor.split("-")
    left = x if horizontal == "left" else x - w if horizontal == "right" else x - w / 2
    top = y - h if vertical == "bottom" else y if vertical == "top" else y - h / 2
    return left, top, left + w, top + h


def overlap(a, b, gap: float = 0.0) -> float:
    """The area two boxes (left, top, right, bottom) share, each grown by ``gap``/2 at its left
    and right."""
    across = min(a[2], b[2]) - max(a[0], b[0]) + gap
    down = min(a[3], b[3]) - max(a[1], b[1])
    return max(0.0, across) * max(0.0, down)


def clash(a, b) -> float:
    """How badly two label boxes meet: the area they share (weighted by :data:`COVER_WEIGHT`)
    plus the area they share grown by :data:`GAP_PX` across."""
    return COVER_WEIGHT * overlap(a, b) + overlap(a, b, GAP_PX)


def choose(xys, texts: list[str], current: list[str]) -> list[str]:
    """The anchor of each label: first in order (the first labels keep their preferred
    corners), its ``current`` one while it meets no label placed before it (:func:`clash`), else
    the first free one of :data:`ANCHORS`, else the one that clashes least; then, for a few
    rounds, each label that still meets another moves to the anchor that clashes least (a
    cluster of three labels at nearly one point: the order alone can leave the middle one no
    free corner)."""
    orders = [[now, *(a for a in ANCHORS if a != now)] if now in ANCHORS else list(ANCHORS) for now in current]
    boxes = [{a: box(xy, text, a) for a in ANCHORS} for xy, text in zip(xys, texts, strict=True)]
    pick: list[str] = []
    for i, order in enumerate(orders):
        covered = [sum(clash(boxes[i][a], boxes[j][pick[j]]) for j in range(i)) for a in order]
        free = next((a for a, c in zip(order, covered, strict=True) if c == 0.0), None)
        pick.append(free if free is not None else order[int(np.argmin(covered))])

    def cost(i: int, a: str) -> float:
        return sum(clash(boxes[i][a], boxes[j][pick[j]]) for j in range(len(pick)) if j != i)

    for _ in range(PASSES):
        moved = False
        for i, order in enumerate(orders):
            now = cost(i, pick[i])
            if now == 0.0:
                continue
            costs = [cost(i, a) for a in order]
            k = int(np.argmin(costs))
            if costs[k] < now:
                pick[i], moved = order[k], True
        if not moved:
            break
    return pick


class LabelLayout:
    """Keeps one browser's labels apart: :meth:`apply` with the labels shown (nodes with ``text``
    and ``anchor``, and their world points) and the camera sets each one's anchor."""

    def __init__(self) -> None:
        self.changes = 0  # anchors changed so far (what a test counts)
        self.seen: tuple | None = None  # what the last layout saw: nothing moved, nothing to do

    def apply(self, items: list[tuple[Any, np.ndarray]], view: View | None) -> int:
        """Choose and set the anchors of ``items`` [(label node, world point)] seen by ``view``
        (None: the browser has not said where its camera is; nothing changes).  Returns how
        many anchors changed."""
        if view is None or not items:
            return 0
        xy, front = view.project(np.array([p for _, p in items], float))
        shown = [i for i in range(len(items)) if front[i]]
        nodes = [items[i][0] for i in shown]
        now = [str(n.anchor) for n in nodes]
        texts = [str(n.text) for n in nodes]
        seen = (np.round(xy[shown], 1).tobytes(), tuple(texts), tuple(now), tuple(map(id, nodes)))
        if seen == self.seen:  # a paused frame, the camera still
            return 0
        new = choose(xy[shown], texts, now)
        changed = 0
        for node, was, anchor in zip(nodes, now, new, strict=True):
            if anchor != was:
                node.anchor = anchor
                changed += 1
        self.changes += changed
        self.seen = (seen[0], seen[1], tuple(new), seen[3])
        return changed
