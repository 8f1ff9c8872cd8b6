"""Small geometry helpers for the scene (pure numpy, no viser): quaternions, polylines as
line segments, and sampling a trajectory's rows.  Nothing here knows a system: what a
system looks like is declared with it (:mod:`nmkane_core.declare.visuals`)."""

from __future__ import annotations

import numpy as np


# --------------------------------------------------------------------------- rotations
def quat_z_to(v) -> tuple[float, float, float, float]:
    """The unit quaternion turning +z onto the direction of v (for members along a segment)."""
    v = np.asarray(v, float)
    v = v / np.linalg.norm(v)
    w = 1.0 + v[2]
    if w < 1e-9:  # v = −z: half turn about x
        return (0.0, 1.0, 0.0, 0.0)
    q = np.array([w, -v[1], v[0], 0.0])  # (1 + z·v, z × v)
    w, x, y, z = (float(c) for c in q / np.linalg.norm(q))
    return (w, x, y, z)


def rotate(wxyz, v) -> np.ndarray:
    """v rotated by the unit quaternion wxyz."""
    w, x, y, z = wxyz
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    return R @ np.asarray(v, float)


def quat_mul(p, q) -> tuple[float, float, float, float]:
    w1, x1, y1, z1 = p
    w2, x2, y2, z2 = q
    return (
        w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
        w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
        w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
        w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
    )


def segments(polyline: np.ndarray) -> np.ndarray:
    """A polyline (N, 3) as line segments (N − 1, 2, 3) for viser."""
    p = np.asarray(polyline, np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


# --------------------------------------------------------------------------- sampling
def decimate(n: int, limit: int) -> np.ndarray:
    """Indices of at most ``limit`` evenly spread rows of n (always the first and the last)."""
    if n <= limit:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, limit).round().astype(int))


def index_at(t: np.ndarray, t_now: float) -> int:
    """The output row shown at time t_now (the last row at or before it)."""
    k = int(np.searchsorted(t, t_now, side="right")) - 1
    return min(max(k, 0), len(t) - 1)


# --------------------------------------------------------------------------- meshes
#: a cylinder no longer than this share of its radius is a disk (a coin, a wheel): its rim is drawn round
DISK = 0.5


def disk_mesh(radius: float, length: float, axis, segments: int = 48, arc: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, triangles) of a disk of ``radius`` and thickness ``length`` along the unit vector
    ``axis`` whose rim is a half circle (a coin's, a tyre's edge): the rim reaches ``radius`` in
    the disk's mid-plane, where a thin-disk model touches the ground.  A flat rim's edges would
    dip below the ground by ``length``/2 · sin(lean) at a lean; a round one at most by
    ``length``/2 · (1 − cos(lean)) (a coin of thickness 0.08 r at 30°: 0.5 % of its radius instead of 2 %)."""
    h = abs(length) / 2
    inner = max(abs(radius) - h, 0.0)
    # the profile (distance from the axis, height), from the top face's centre round to the bottom's
    a = np.linspace(np.pi / 2, -np.pi / 2, arc + 1)
    profile = np.array([(0.0, h), *zip(inner + h * np.cos(a), h * np.sin(a), strict=True), (0.0, -h)])
    n = np.asarray(axis, float) / np.linalg.norm(axis)
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    t = np.linspace(0.0, 2 * np.pi, segments, endpoint=False)
    ring = np.cos(t)[:, None] * e1 + np.sin(t)[:, None] * e2  # (segments, 3)
    verts = (profile[:, None, 0:1] * ring[None] + profile[:, None, 1:2] * n).reshape(-1, 3)
    faces = []
    m = len(profile)
    for i in range(m - 1):  # quads between profile points i and i + 1, split in two
        for j in range(segments):
            a0, a1 = i * segments + j, i * segments + (j + 1) % segments
            b0, b1 = a0 + segments, a1 + segments
            if i > 0:  # (the top face's centre is one point: its second triangle has no area)
                faces.append((a0, b1, a1))
            if i < m - 2:  # (so is the bottom face's)
                faces.append((a0, b0, b1))
    return verts.astype(np.float32), np.array(faces, np.uint32)
