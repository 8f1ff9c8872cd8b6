"""A system's declared visuals (:mod:`nmkane_core.visuals`) as a viser scene.

Scene tree per system: ``/sys/<name>`` (hidden while another system is chosen), under it
``frames/<frame>`` (posed per animation frame: position and quaternion) with the shapes
attached to each frame as children at their constant offsets, ``world/<shape>`` for
shapes on the world or at points, and ``ground``.  Poses are computed once per trajectory
for every output row (the compiled pose functions are vectorized); a frame then only
picks a row.  A system that declares no visuals is drawn as a point at its first three
coordinates (missing ones 0), with its trace.
"""

from __future__ import annotations

import numpy as np

from nmkane_core.visuals import axis_wxyz, compile_visuals, rotation_to_wxyz

from . import geometry as geo

BIG = 1e6  # coordinates are clipped to ±BIG for float32 nodes


def _clip(a):
    return np.clip(np.nan_to_num(np.asarray(a, float), nan=0.0), -BIG, BIG)


class DeclaredScene:
    """The viser nodes of one system's visuals, and their poses over a trajectory."""

    def __init__(self, scene, system):
        self.scene, self.system = scene, system
        self.prefix = f"/sys/{system.name}"
        self.root = scene.add_frame(self.prefix, show_axes=False, visible=False)
        self.compiled = compile_visuals(system)
        self.frames: dict = {}  # frame name -> node
        self.dynamic: list = []  # (node, kind, point indices)
        self.traces: dict = {}
        self.sizes_for = None
        self.frame_poses: dict = {}  # frame name -> (positions (n,3), wxyz (n,4))
        self.points: list[np.ndarray] = []
        self.bounds_ = None

    # ---------------------------------------------------------------- geometry
    def shape(self, params: dict) -> None:
        """(Re)build the shapes for these parameters (sizes may depend on them)."""
        key = tuple(sorted(params.items()))
        if key == self.sizes_for:
            return
        self.sizes_for = key
        sc, pre = self.scene, self.prefix
        cv = self.compiled
        self.dynamic, self.traces = [], {}
        if cv is None:
            sc.add_grid(
                f"{pre}/ground",
                width=40.0,
                height=40.0,
                plane="xy",
                cell_size=0.5,
                section_size=2.0,
                plane_color=(232, 236, 226),
                plane_opacity=0.5,
                shadow_opacity=0.2,
            )
            node = sc.add_icosphere(f"{pre}/world/point", radius=0.05, color=(200, 80, 40))
            self.dynamic.append((node, "point", [0]))
            self.traces["trace"] = sc.add_line_segments(
                f"{pre}/world/trace",
                points=np.zeros((1, 2, 3), np.float32),
                colors=(214, 48, 39),
                thickness=2.0,
                thickness_units="screen",
            )
            return
        sizes = cv.sizes(params)
        for name in cv.frames:
            self.frames[name] = sc.add_frame(f"{pre}/frames/{name}", show_axes=False)
        for s in cv.shapes:
            i, n = s["size"]
            size = sizes[i : i + n]
            off = tuple(float(v) for v in sizes[s["offset"] : s["offset"] + 3])
            parent = f"{pre}/frames/{s['frame']}" if s["frame"] else f"{pre}/world"
            path, color, op = f"{parent}/{s['name']}", tuple(s["color"]), s["opacity"]
            kw = {"opacity": op} if op < 1 else {}
            kind = s["kind"]
            if kind == "box":
                sc.add_box(path, color=color, dimensions=tuple(float(abs(v)) for v in size), position=off, **kw)
            elif kind == "cylinder":
                sc.add_cylinder(
                    path,
                    radius=float(abs(size[0])),
                    height=float(abs(size[1])),
                    color=color,
                    wxyz=axis_wxyz(s["axis"]),
                    position=off,
                    radial_segments=48,
                    **kw,
                )
            elif kind == "sphere":
                node = sc.add_icosphere(path, radius=float(abs(size[0])), color=color, position=off, **kw)
                if s["points"]:
                    self.dynamic.append((node, "point", s["points"]))
            elif kind == "segments":
                npairs = len(s["points"]) // 2
                node = sc.add_line_segments(
                    path,
                    points=np.zeros((npairs, 2, 3), np.float32),
                    colors=color,
                    thickness=3.0,
                    thickness_units="screen",
                )
                self.dynamic.append((node, "segments", s["points"]))
            elif kind == "trace":
                self.traces[s["name"]] = (
                    sc.add_line_segments(
                        path,
                        points=np.zeros((1, 2, 3), np.float32),
                        colors=color,
                        thickness=2.5,
                        thickness_units="screen",
                    ),
                    s["points"][0],
                )
            elif kind == "ground":
                sc.add_grid(
                    f"{pre}/ground",
                    width=200.0,
                    height=200.0,
                    plane="xy",
                    cell_size=0.5,
                    section_size=2.0,
                    cell_color=(205, 208, 200),
                    section_color=(150, 155, 145),
                    plane_color=color,
                    plane_opacity=0.6,
                    shadow_opacity=0.25,
                    infinite_grid=True,
                    fade_distance=120.0,
                    position=(0.0, 0.0, float(size[0])),
                )

    # ---------------------------------------------------------------- poses
    def install(self, run, params: dict) -> None:
        """Poses of every row of a run (and the traces)."""
        self.shape(params)
        states = dict(run.state)
        cv = self.compiled
        if cv is None:
            names = list(self.system.coordinates)[:3]
            cols = [states[n] for n in names] + [np.zeros(len(run.t))] * (3 - len(names))
            pts = _clip(np.column_stack(cols))
            self.points = [pts]
            self.frame_poses = {}
            self.traces["trace"].points = geo.segments(pts[geo.decimate(len(pts), 2000)])
            self.bounds_ = (pts.min(0), pts.max(0))
            return
        frames, out = cv.frame_poses(states, params)
        self.frame_poses = {k: (_clip(p), rotation_to_wxyz(np.nan_to_num(R))) for k, (p, R) in frames.items()}
        self.points = out
        lo, hi = [], []
        for pos, _ in self.frame_poses.values():
            lo.append(pos.min(0)), hi.append(pos.max(0))
        for node, i in self.traces.values():
            pts = _clip(cv.point(out, i))
            node.points = geo.segments(pts[geo.decimate(len(pts), 2000)])
            lo.append(pts.min(0)), hi.append(pts.max(0))
        if lo:
            self.bounds_ = (np.min(lo, axis=0), np.max(hi, axis=0))

    def pose(self, k: int) -> None:
        """Put every node at output row k."""
        for name, (pos, q) in self.frame_poses.items():
            node = self.frames[name]
            node.position = tuple(pos[k])
            node.wxyz = tuple(q[k])
        if not self.points:
            return
        for node, kind, idx in self.dynamic:
            if self.compiled is None:
                node.position = tuple(self.points[0][k])
            elif kind == "point":
                node.position = tuple(_clip([float(self.points[idx[0] + j][k]) for j in range(3)]))
            else:
                pts = np.array([[float(self.points[i + j][k]) for j in range(3)] for i in idx], np.float32)
                node.points = _clip(pts).reshape(-1, 2, 3).astype(np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lowest, highest) corner of everything that moves over the installed run."""
        return self.bounds_


def fit_camera(bounds, fov: float = 1.309, panel_shift: float = 0.4) -> tuple[np.ndarray, np.ndarray]:
    """(look_at, position) framing a box: seen from the front-right and above, far enough for the
    box's bounding sphere (plus a margin) to fit the vertical field of view ``fov`` (radians,
    viser's default 75°).  The control panel covers the right of the page, so the box is moved
    left of the centre by ``panel_shift`` of the half-height of the view at its distance."""
    lo, hi = (np.asarray(b, float) for b in bounds)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.4)
    direction = np.array([0.55, -0.75, 0.5])
    direction /= np.linalg.norm(direction)
    dist = 1.1 * radius / np.tan(fov / 2)
    right = np.cross(-direction, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    look_at = centre + right * panel_shift * dist * np.tan(fov / 2)
    return look_at, look_at + direction * dist
