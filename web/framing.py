"""What the camera frames of a declared scene (pure numpy): the box of the mechanism's parts at
every output row, the point a following camera follows, and the least box a small part is
framed in (:mod:`web.camera` looks at them; :class:`web.declared.DeclaredScene` keeps them).

The **parts** are the solids on the system's frames (each frame's solids as one box in the
frame's coordinates, turned and moved with it) and the balls and line segments placed at
points that move with the state (a load on its thread, a bar) — not the paths their points
trace, the ground or fixed surfaces.
"""

from __future__ import annotations

import numpy as np

Bounds = tuple[np.ndarray, np.ndarray]

#: a mechanism smaller than this share of the system's largest shape on every side (a small
#: body on a wide surface) is framed as a box of that size, around it, with some of the surface
CONTEXT = 0.75


def parts_rows(frames: dict, local: dict, movers: list, n: int) -> Bounds | None:
    """Per output row (n of them), the box (lowest, highest corner; each (n, 3)) of the parts.

    ``frames``: frame name -> (origins (n, 3), rotation matrices (n, 3, 3)), either of one row
    when constant; ``local``: frame name -> the (lo, hi) boxes of its solids in its coordinates
    (a frame without solids counts with its origin); ``movers``: (node, points (n, m, 3)) of the
    moving balls and lines (``node.body``: a ball, reaching ``node.reach`` from its point;
    ``node.how == "segments"``: a line), other moving nodes (labels) are left out."""
    los, his = [], []
    for name, (p, R) in frames.items():
        p = np.broadcast_to(np.nan_to_num(np.asarray(p, float)).reshape(-1, 3), (n, 3))
        boxes = local.get(name)
        if not boxes:
            los.append(p)
            his.append(p)
            continue
        lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
        R = np.broadcast_to(np.nan_to_num(np.asarray(R, float)).reshape(-1, 3, 3), (n, 3, 3))
        centre = p + np.einsum("nij,j->ni", R, (lo + hi) / 2)
        half = np.einsum("nij,j->ni", np.abs(R), (hi - lo) / 2)  # the turned box's axis-aligned half sides
        los.append(centre - half)
        his.append(centre + half)
    for node, rows in movers:
        if node.body or node.how == "segments":
            pts = np.asarray(rows, float)
            los.append(pts.min(axis=1) - node.reach)
            his.append(pts.max(axis=1) + node.reach)
    if not los:
        return None
    return np.min(los, axis=0), np.max(his, axis=0)


def centre_rows(frame_poses: dict, rows: list, n: int) -> np.ndarray:
    """Per output row, the point a following camera follows: the mean of the frames' origins
    (``frame_poses``: name -> (origins, quaternions)), else the first moving node's first point
    (``rows``: per moving node its points (n, m, 3)), else the world's origin."""
    if frame_poses:
        return np.mean([np.broadcast_to(p.reshape(-1, 3), (n, 3)) for p, _ in frame_poses.values()], axis=0)
    if rows:
        return np.broadcast_to(rows[0][:, 0].astype(float).reshape(-1, 3), (n, 3))
    return np.zeros((n, 3))


def at_least(lo: np.ndarray, hi: np.ndarray, extent: float) -> Bounds:
    """The box (lo, hi), or, when it is smaller than :data:`CONTEXT` times ``extent`` (the
    system's largest shape) on every side, that size on each side around its centre."""
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    least = CONTEXT * extent
    if 2 * float(np.max(half)) < least:
        half = np.maximum(half, least / 2)
    return mid - half, mid + half
