"""What the mechanisms look like, from the paper's kinematics (no viser here).

Appell–Hamel (Fig. 1, eqs. (51)–(59)): the load P at (x, y, z) moves along the frame's
vertical bar; the frame's heading is θ; the wheel centre is o = (x, y) − ρ(cos θ, sin θ)
at height a; the wheel (radius a, drum radius b) spins by φ about its axle
(−sin θ, cos θ, 0).  Positions below are in the *heading frame* attached at P's
horizontal position (x axis along (cos θ, sin θ)), so the whole frame is one pose.

The pulleys sit at height ``pulley_height`` — the paper gives none; we put them above the
load's starting height z0 (+2 m) so the thread can hang P at z0.  The load keeps falling
below the plane in the paper's model; the bar runs down a shaft through the ground.
"""

from __future__ import annotations

import math

import numpy as np


def pulley_height(params: dict) -> float:
    return max(params["z0"], params["a"] + params["b"]) + 2.0


def heading_wxyz(theta: float) -> tuple[float, float, float, float]:
    """Rotation by θ about +z (the frame's heading)."""
    return (math.cos(theta / 2), 0.0, 0.0, math.sin(theta / 2))


def spin_wxyz(phi: float) -> tuple[float, float, float, float]:
    """Rotation by φ about the axle, the heading frame's +y (rolling forward for φ̇ > 0)."""
    return (math.cos(phi / 2), 0.0, math.sin(phi / 2), 0.0)


def wheel_centre_local(params: dict) -> tuple[float, float, float]:
    """o in the heading frame: ρ behind P along the heading, at height a."""
    return (-params["rho"], 0.0, params["a"])


def wheel_centre_world(params: dict, theta: float, x: float, y: float) -> np.ndarray:
    return np.array([x - params["rho"] * math.cos(theta), y - params["rho"] * math.sin(theta), params["a"]])


def thread_local(params: dict, z: float) -> np.ndarray:
    """The thread as line segments (N, 2, 3) in the heading frame: drum top → pulley above
    the wheel → pulley above P → down to the load."""
    h = pulley_height(params)
    o = wheel_centre_local(params)
    drum_top = (o[0], 0.0, o[2] + params["b"])
    p1 = (o[0], 0.0, h)
    p2 = (0.0, 0.0, h)
    load = (0.0, 0.0, z)
    return np.array([[drum_top, p1], [p1, p2], [p2, load]], dtype=np.float32)


def parabola_trough(l0: float, half_width: float = 1.6, depth: float = 0.6, n: int = 48):
    """The sliding particle's surface y = l0 − x²/l0 (y down) as a trough mesh in world
    coordinates (x, lane, −y): vertices, faces."""
    xs = np.linspace(-half_width, half_width, n)
    zs = xs ** 2 / l0 - l0                # world height = −y on the surface
    verts = []
    for lane in (-depth, depth):
        for xv, zv in zip(xs, zs):
            verts.append((xv, lane, zv))
    verts = np.array(verts, dtype=np.float32)
    faces = []
    for i in range(n - 1):
        a, b, c, d = i, i + 1, n + i, n + i + 1
        faces += [(a, b, c), (b, d, c)]
    return verts, np.array(faces, dtype=np.uint32)


def decimate(n: int, limit: int = 1500) -> np.ndarray:
    """Indices of at most ``limit`` samples of n rows (always the first and the last)."""
    if n <= limit:
        return np.arange(n)
    idx = np.linspace(0, n - 1, limit).round().astype(int)
    return np.unique(idx)
