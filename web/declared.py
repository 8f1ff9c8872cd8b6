"""A system's declared visuals (:mod:`nmkane_core.declare.visuals`) as a viser scene.

Scene tree per system: ``/sys/<name>`` (hidden while another system is chosen), under it
``frames/<frame>`` (posed per animation frame: position and quaternion) with the shapes
attached to each frame as children at their constant offsets, ``world/<shape>`` for
shapes on the world or at points, and ``ground``.  Poses are computed once per trajectory
for every output row (the compiled pose functions are vectorized); a frame then only
picks a row.  A system that declares no visuals is drawn as a point at its first three
coordinates (missing ones 0), with its trace.

A *ghost* (``ghost=(r, g, b)``) draws another run of the same system (a compare run) under
``/sys/<name>/ghost<i>``: every moving shape translucent in one colour; the fixed ones
(ground, surfaces, shapes on the world) are drawn once, by the main scene.
"""

from __future__ import annotations

import numpy as np

from nmkane_core.kernel.built import built
from nmkane_core.kernel.visuals import AXES, axis_wxyz, compile_visuals, rotation_to_wxyz

from . import geometry as geo

BIG = 1e6  # coordinates are clipped to ±BIG for float32 nodes
GHOST_OPACITY = 0.35
SOLID = ("box", "cylinder", "sphere")
LINE_PX = {"segments": 3.0, "trace": 2.5}  # default line thickness in screen pixels


def _clip(a):
    return np.clip(np.nan_to_num(np.asarray(a, float), nan=0.0), -BIG, BIG)


class DeclaredScene:
    """The viser nodes of one system's visuals, and their poses over a trajectory."""

    def __init__(self, scene, system, ghost: tuple | None = None, index: int = 0):
        """``system``: a core System; ``ghost``: the colour of a ghost scene (None: the main
        one), ``index`` its number under the main scene's node."""
        self.scene, self.system, self.ghost = scene, system, ghost
        if ghost is None:
            self.prefix = f"/sys/{system.name}"
            self.root = scene.add_frame(self.prefix, show_axes=False, visible=False)
        else:
            self.prefix = f"/sys/{system.name}/ghost{index}"
            self.root = scene.add_frame(self.prefix, show_axes=False, visible=True)
        self.compiled = compile_visuals(system)
        self.frames: dict = {}  # frame name -> node
        self.dynamic: list = []  # (node, kind, point indices)
        self.traces: dict = {}
        self.sizes_for = None
        self.frame_poses: dict = {}  # frame name -> (positions (n,3), wxyz (n,4))
        self.points: list[np.ndarray] = []
        self.rows: list[np.ndarray] = []
        self.moving: list[bool] = []
        self.shown: int | None = None  # the output row the nodes show
        self.extent = 0.5  # a length of the system itself: its largest shape (m)
        self.fixed_points: list[np.ndarray] = []  # vertices of fixed surfaces (for the bounds)
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
        self.dynamic, self.traces, self.fixed_points = [], {}, []
        if cv is None and self.ghost is not None:
            node = sc.add_icosphere(f"{pre}/world/point", radius=0.05, color=self.ghost, opacity=GHOST_OPACITY)
            self.dynamic.append((node, "point", [0]))
            return
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
        self.extent = self._extent(cv, sizes)
        for name in cv.frames:
            self.frames[name] = sc.add_frame(f"{pre}/frames/{name}", show_axes=False)
        for s in cv.shapes:
            i, n = s["size"]
            size = sizes[i : i + n]
            off = tuple(float(v) for v in sizes[s["offset"] : s["offset"] + 3])
            parent = f"{pre}/frames/{s['frame']}" if s["frame"] else f"{pre}/world"
            path, color, op = f"{parent}/{s['name']}", tuple(s["color"]), s["opacity"]
            kind = s["kind"]
            fixed = kind in ("ground", "strip") or (s["frame"] is None and not s["points"])
            if self.ghost is not None:
                if fixed:
                    continue  # drawn once, by the main scene
                color, op = self.ghost, min(op, GHOST_OPACITY)
            kw = {"opacity": op} if op < 1 else {}
            px = s.get("thickness") or LINE_PX.get(kind, 3.0)
            if kind == "rod":
                p = np.array(off)
                q = np.array([float(v) for v in sizes[s["end"] : s["end"] + 3]])
                length = float(np.linalg.norm(q - p))
                t = float(abs(size[0]))
                sc.add_box(
                    path,
                    color=color,
                    dimensions=(t, t, max(length, 1e-3)),
                    position=tuple((p + q) / 2),
                    wxyz=geo.quat_z_to(q - p) if length > 0 else (1.0, 0.0, 0.0, 0.0),
                    **kw,
                )
            elif kind == "label":
                if self.ghost is None and s["points"]:
                    node = sc.add_label(path, s.get("text", ""), anchor="bottom-left")
                    self.dynamic.append((node, "point", s["points"]))
                elif self.ghost is None:  # on a frame: moves with it
                    sc.add_label(path, s.get("text", ""), position=off, anchor="bottom-left")
            elif kind == "strip":
                verts, faces = strip_mesh(
                    np.array([[float(v) for v in sizes[j : j + 3]] for j in s["path"]]), float(size[0]), s["axis"]
                )
                sc.add_mesh_simple(path, verts, faces, color=color, side="double", cast_shadow=False, **kw)
                self.fixed_points.append(verts)
            elif kind == "box":
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
                    thickness=px,
                    thickness_units="screen",
                )
                self.dynamic.append((node, "segments", s["points"]))
            elif kind == "trace":
                self.traces[s["name"]] = (
                    sc.add_line_segments(
                        path,
                        points=np.zeros((1, 2, 3), np.float32),
                        colors=color,
                        thickness=px,
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

    @staticmethod
    def _extent(cv, sizes) -> float:
        """A length of the system itself (for the camera): its largest solid shape or fixed
        surface (frame members, rods, are left out: a tall frame is not the thing to frame)."""
        out = [abs(float(v)) for s in cv.shapes if s["kind"] in SOLID for v in sizes[s["size"][0] : sum(s["size"])]]
        for s in cv.shapes:
            if s["kind"] == "strip":
                pts = np.array([sizes[j : j + 3] for j in s["path"]])
                out.append(float(np.linalg.norm(pts.max(0) - pts.min(0))) / 2)
        return max(out, default=0.5)

    # ---------------------------------------------------------------- poses
    def install(self, run, params: dict) -> None:
        """Poses of every row of a run (and the traces)."""
        self.shown = None
        self.shape(params)
        states = dict(run.state)
        cv = self.compiled
        if cv is None:
            names = list(built(self.system).coordinates)[:3]
            cols = [states[n] for n in names] + [np.zeros(len(run.t))] * (3 - len(names))
            pts = _clip(np.column_stack(cols))
            self.points = [pts]
            self.frame_poses = {}
            if "trace" in self.traces:
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
        self.rows, self.moving = [], []  # per shape at points: its points over the run (n, m, 3)
        for node, kind, idx in self.dynamic:  # balls at points, segment ends (a thread's top)
            pts = _clip(np.stack([cv.point(out, i) for i in idx], axis=1)).astype(np.float32)
            moving = bool(np.any(pts != pts[:1]))
            self.rows.append(pts)
            self.moving.append(moving)
            if not moving:  # fixed (a bowl's rings): placed once, drawn by the main scene only
                self._place(node, kind, pts[0])
                node.visible = self.ghost is None
            lo.append(pts.min((0, 1))), hi.append(pts.max((0, 1)))
        for pts in self.fixed_points:
            lo.append(pts.min(0)), hi.append(pts.max(0))
        if lo:
            self.bounds_ = (np.min(lo, axis=0), np.max(hi, axis=0))

    def pose(self, k: int) -> None:
        """Put every node at output row k (nothing is sent when row k is already shown)."""
        if k == self.shown:
            return
        prev, self.shown = self.shown, k
        for name, (pos, q) in self.frame_poses.items():
            node = self.frames[name]
            node.position = tuple(pos[k])
            node.wxyz = tuple(q[k])
        if not self.points:
            return
        if self.compiled is None:
            for node, _, _ in self.dynamic:
                node.position = tuple(self.points[0][k])
            return
        for (node, kind, _), rows, moving in zip(self.dynamic, self.rows, self.moving, strict=True):
            if moving and (prev is None or not np.array_equal(rows[k], rows[prev])):
                self._place(node, kind, rows[k])

    @staticmethod
    def _place(node, kind: str, pts: np.ndarray) -> None:
        """Put a ball or label (kind "point") or line segments at these points (m, 3)."""
        if kind == "point":
            node.position = tuple(float(v) for v in pts[0])
        else:
            node.points = pts.reshape(-1, 2, 3)

    def bounds_at(self, k: int) -> tuple[np.ndarray, np.ndarray] | None:
        """(lowest, highest) corner of the frame origins and moving points at output row k."""
        pts = [pos[min(k, len(pos) - 1)] for pos, _ in self.frame_poses.values()]
        pts += [p for rows in self.rows for p in rows[min(k, len(rows) - 1)].astype(float)]
        if self.compiled is None and self.points:
            pts.append(self.points[0][min(k, len(self.points[0]) - 1)])
        if not pts:
            return None
        return np.min(pts, axis=0), np.max(pts, axis=0)

    def bounds(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(lowest, highest) corner of everything that moves over the installed run."""
        return self.bounds_


def strip_mesh(path: np.ndarray, width: float, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """A polyline (n, 3) swept by ``width`` along ``axis`` (centred): (vertices, faces)."""
    d = np.array(AXES[axis]) * width / 2
    n = len(path)
    verts = np.vstack([path - d, path + d]).astype(np.float32)
    faces = [(i, i + 1, n + i) for i in range(n - 1)] + [(i + 1, n + i + 1, n + i) for i in range(n - 1)]
    return verts, np.array(faces, np.uint32)


def fit_camera(bounds, fov: float = 1.309, panel_shift: float = 0.4, direction=None) -> tuple[np.ndarray, np.ndarray]:
    """(look_at, position) framing a box: seen from ``direction`` (from the box to the camera;
    default front-right and above), far enough for the box's bounding sphere (plus a margin)
    to fit the vertical field of view ``fov`` (radians, viser's default 75°).  The control
    panel covers the right of the page, so the box is moved left of the centre by
    ``panel_shift`` of the half-height of the view at its distance."""
    lo, hi = (np.asarray(b, float) for b in bounds)
    centre = (lo + hi) / 2
    radius = max(float(np.linalg.norm(hi - lo)) / 2, 0.4)
    direction = np.array([0.55, -0.75, 0.5] if direction is None else direction, float)
    direction /= np.linalg.norm(direction)
    dist = 1.05 * radius / np.sin(fov / 2)  # the bounding sphere inside the cone of view
    right = np.cross(-direction, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    look_at = centre + right * panel_shift * dist * np.tan(fov / 2)
    return look_at, look_at + direction * dist
