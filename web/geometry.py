"""What the mechanisms look like, from the paper's kinematics (pure numpy, no viser).

Appell–Hamel (Fig. 1, eqs. (51)–(59)).  Everything that rides on the frame is placed in
the *body frame*: origin at P's horizontal position (x, y) on the plane, local x along
the heading (cos θ, sin θ), local y along the wheel's axle (−sin θ, cos θ), z up.  In it

* the load P is at (0, 0, z) on the frame's vertical bar,
* the wheel centre o is at (−ρ, 0, a)  — i.e. o = (x, y) − ρ(cos θ, sin θ) at height a,
  (53)–(54) — and the wheel spins by φ about local +y (rolling forward for φ̇ > 0, (51)),
* the drum (radius b) sits on the wheel's axle beside the disk; the thread leaves its
  rear side vertically, runs over two pulleys and hangs P: z = z0 − bφ (59).

Pulley height is not given by the paper.  We put the pulley axles 2 m above the highest
point the load or the wheel can have at the start, ``h = max(z0, 2a + b) + 2``, so the
thread can hang P at z0.  Both pulleys are drawn with radius b, so the thread rises
vertically from the drum and falls vertically onto P; their centres are then ρ − b apart
(massless pulleys: their size does not enter the dynamics).  In the paper's model the load
keeps falling below the plane (z < 0): the bar runs down through a hole in the plane as
deep as the run needs — nothing is clamped.

Sliding particle (Example 2, (114)): y points down, the surface ψ = y + x²/l0 − l0 = 0 is
the bowl y = l0 − x²/l0; shown at height −y.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

PULLEY_CLEARANCE = 2.0  # m, pulleys above the load's (or wheel's) highest start point
LOAD_RADIUS = 0.35  # m, the load P drawn as a ball (the paper's P is a particle)
BAR_OFFSET = -0.22  # m, P's guide bar runs just behind the thread (local y)
MEMBER = 0.18  # m, thickness of the frame's members


# --------------------------------------------------------------------------- rotations
def heading_wxyz(theta: float) -> tuple[float, float, float, float]:
    """Rotation by θ about +z: the body frame's heading."""
    return (math.cos(theta / 2), 0.0, 0.0, math.sin(theta / 2))


def spin_wxyz(phi: float) -> tuple[float, float, float, float]:
    """Rotation by φ about the axle (the body frame's +y): the wheel's spin."""
    return (math.cos(phi / 2), 0.0, math.sin(phi / 2), 0.0)


AXIS_Z_TO_Y = (math.cos(-math.pi / 4), math.sin(-math.pi / 4), 0.0, 0.0)  # cylinders' axis → +y


def quat_z_to(v) -> tuple[float, float, float, float]:
    """The unit quaternion turning +z onto the direction of v (for members along a segment)."""
    v = np.asarray(v, float)
    v = v / np.linalg.norm(v)
    w = 1.0 + v[2]
    if w < 1e-9:  # v = −z: half turn about x
        return (0.0, 1.0, 0.0, 0.0)
    q = np.array([w, -v[1], v[0], 0.0])  # (1 + z·v, z × v)
    q /= np.linalg.norm(q)
    return tuple(float(c) for c in q)


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


# --------------------------------------------------------------------------- Appell–Hamel
@dataclass(frozen=True)
class Layout:
    """Sizes and body-frame positions of the mechanism's parts for parameters a, b, ρ, z0."""

    a: float
    b: float
    rho: float
    z0: float

    @classmethod
    def of(cls, params: dict) -> Layout:
        return cls(float(params["a"]), float(params["b"]), float(params["rho"]), float(params["z0"]))

    # heights and offsets ------------------------------------------------------------
    @property
    def h(self) -> float:
        """Height of the pulley axles."""
        return max(self.z0, 2 * self.a + self.b) + PULLEY_CLEARANCE

    @property
    def wheel_width(self) -> float:
        return 0.15 * self.a

    @property
    def drum_length(self) -> float:
        return 0.3 * self.a

    @property
    def drum_y(self) -> float:
        """The drum's centre along the axle (beside the disk, thread plane of pulley 1)."""
        return self.wheel_width / 2 + 0.05 * self.a + self.drum_length / 2

    @property
    def fork_y(self) -> tuple[float, float]:
        """The wheel fork's two struts along the axle (either side of disk and drum)."""
        return (-(self.wheel_width / 2 + 0.15), self.drum_y + self.drum_length / 2 + 0.15)

    @property
    def wheel_centre(self) -> tuple[float, float, float]:
        """o in the body frame: ρ behind P along the heading, at height a."""
        return (-self.rho, 0.0, self.a)

    @property
    def pulleys(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """Centres of pulley 1 (above the drum) and pulley 2 (above P's bar), radius b."""
        return (-self.rho, self.drum_y, self.h), (-self.b, 0.0, self.h)

    # members ------------------------------------------------------------------------
    def members(self, bottom: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The frame's straight members as segments (start, end) in the body frame; P's bar
        reaches down to ``bottom`` (below the plane when the load goes there)."""
        h, rho = self.h, self.rho
        yl, yr = self.fork_y
        leg_x = -0.6
        spread = max(3.0, 0.15 * h)
        P = lambda *c: np.array(c, float)  # noqa: E731
        return {
            "beam": (P(-rho - 0.4, yl, h), P(0.4, yl, h)),  # carries the pulleys
            "fork_left": (P(-rho, yl, self.a), P(-rho, yl, h)),  # holds the axle
            "fork_right": (P(-rho, yr, self.a), P(-rho, yr, h)),
            "fork_top": (P(-rho, yl, h), P(-rho, yr, h)),  # pulley 1's axle
            "pulley2_axle": (P(-self.b, yl, h), P(-self.b, 0.15, h)),
            "bar": (P(0.0, BAR_OFFSET, bottom), P(0.0, BAR_OFFSET, h)),  # P's guide
            "bar_arm": (P(0.0, BAR_OFFSET, h), P(0.4, yl, h)),
            "leg_left": (P(leg_x, yl, h), P(leg_x, yl - spread, 0.0)),  # the two legs that
            "leg_right": (P(leg_x, yl, h), P(leg_x, yl + spread, 0.0)),  # slide on the plane
            "axle": (P(-rho, yl, self.a), P(-rho, yr, self.a)),
        }

    def feet(self) -> list[np.ndarray]:
        yl = self.fork_y[0]
        spread = max(3.0, 0.15 * self.h)
        return [np.array([-0.6, yl - spread, 0.0]), np.array([-0.6, yl + spread, 0.0])]

    # thread -------------------------------------------------------------------------
    def thread_fixed(self, arc_points: int = 8) -> np.ndarray:
        """The thread from the drum over both pulleys to the top of the hanging run, as a
        polyline (N, 3) in the body frame (it does not move relative to the frame)."""
        (p1x, p1y, h), (p2x, _, _) = self.pulleys
        b, a = self.b, self.a
        pts = [(-self.rho - b, p1y, a), (-self.rho - b, p1y, h)]  # off the drum's rear
        for ang in np.linspace(math.pi, math.pi / 2, arc_points)[1:]:  # over pulley 1
            pts.append((p1x + b * math.cos(ang), p1y, h + b * math.sin(ang)))
        for ang in np.linspace(math.pi / 2, 0.0, arc_points):  # over pulley 2
            pts.append((p2x + b * math.cos(ang), 0.0, h + b * math.sin(ang)))
        return np.array(pts, float)

    def hanging(self, z: float) -> np.ndarray:
        """The thread's vertical run from pulley 2 down to the load at height z: (1, 2, 3)."""
        return np.array([[[0.0, 0.0, self.h], [0.0, 0.0, z + LOAD_RADIUS]]], np.float32)


def segments(polyline: np.ndarray) -> np.ndarray:
    """A polyline (N, 3) as line segments (N − 1, 2, 3) for viser."""
    p = np.asarray(polyline, np.float32)
    return np.stack([p[:-1], p[1:]], axis=1)


def wheel_centre_world(params: dict, theta: float, x: float, y: float) -> np.ndarray:
    """o = (x − ρ cos θ, y − ρ sin θ, a), eqs. (53)–(54) integrated."""
    return np.array([x - params["rho"] * math.cos(theta), y - params["rho"] * math.sin(theta), params["a"]])


def axle_world(theta: float) -> np.ndarray:
    """The wheel's axle direction (−sin θ, cos θ, 0)."""
    return np.array([-math.sin(theta), math.cos(theta), 0.0])


def pit_bottom(z_min: float) -> float:
    """How deep P's bar must reach: 1 m below the lowest point of the load (or the plane)."""
    return min(float(z_min), 0.0) - LOAD_RADIUS - 1.0


def trace_segments(x: np.ndarray, y: np.ndarray, limit: int = 2000, height: float = 0.03) -> np.ndarray:
    """P's intercept on the plane (the paper's Fig. 7) as line segments, at most ``limit``."""
    idx = decimate(len(x), limit)
    big = 1e7  # keep float32 finite for runaway runs
    pts = np.column_stack([np.clip(x[idx], -big, big), np.clip(y[idx], -big, big), np.full(len(idx), height)]).astype(
        np.float32
    )
    if len(pts) < 2:
        pts = np.vstack([pts, pts]) if len(pts) else np.zeros((2, 3), np.float32)
    return segments(pts)


# --------------------------------------------------------------------------- sliding particle
def bowl_height(x, l0: float):
    """Height (−y) of the surface ψ = 0 (114) above x."""
    return np.asarray(x) ** 2 / l0 - l0


def particle_bowl(l0: float, half_width: float, depth: float = 0.5, n: int = 64):
    """The surface ψ = 0 as a trough mesh (vertices, faces) in a lane's frame (x, lane, −y)."""
    xs = np.linspace(-half_width, half_width, n)
    zs = bowl_height(xs, l0)
    verts = np.array([(xv, lane, zv) for lane in (-depth, depth) for xv, zv in zip(xs, zs, strict=True)], np.float32)
    faces = []
    for i in range(n - 1):
        a, b, c, d = i, i + 1, n + i, n + i + 1
        faces += [(a, b, c), (b, d, c)]
    return verts, np.array(faces, np.uint32)


def particle_position(x: float, y: float) -> tuple[float, float, float]:
    """Where a lane draws the particle: (x, 0, −y) (y points down in the paper)."""
    return (float(x), 0.0, float(-y))


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
