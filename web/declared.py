"""A system's declared visuals (:mod:`nmkane_core.declare.visuals`) as a viser scene.

Scene tree per system: ``/sys/<name>`` (hidden while another system is chosen), under it
``frames/<frame>`` (posed per animation frame: position and quaternion) with the shapes
attached to each frame as children at their constant offsets, ``world/<shape>`` for
shapes on the world or at points, and ``ground``.  Poses are computed once per trajectory
for every output row (the compiled pose functions are vectorized); a frame then only
picks a row.  A system that declares no visuals is drawn as a point at its first three
coordinates (missing ones 0), with its trace.

At install, each output row's box of the mechanism's parts and the point a following camera
follows are computed too (:mod:`web.framing`): what the camera frames (:mod:`web.camera`).

A *ghost* (``ghost=(r, g, b)``) draws another run of the same system (a compare run) under
``/sys/<name>/ghost<i>``: every moving shape translucent in one colour; the fixed ones
(ground, surfaces, shapes on the world) are drawn once, by the main scene.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from nmkane_core.declare import visuals as decl
from nmkane_core.kernel.built import built
from nmkane_core.kernel.visuals import AXES, CompiledVisuals, Slot, axis_wxyz, compile_visuals, rotation_to_wxyz

from . import framing
from . import geometry as geo

BIG = 1e6  # coordinates are clipped to ±BIG for float32 nodes
GHOST_OPACITY = 0.35
GROUND_OPACITY = 0.6  # the ground plane's
#: … when a part goes below it (a load falling through a hole in the plane): seen through it
GROUND_SEEN_THROUGH = 0.2
LINE_PX = {"segments": 3.0, "trace": 2.5}  # default line thickness in screen pixels
Bounds = tuple[np.ndarray, np.ndarray]


def _clip(a):
    return np.clip(np.nan_to_num(np.asarray(a, float), nan=0.0), -BIG, BIG)


@dataclass
class Moving:
    """A node placed at world points that may move with the state: a ball or a label
    (``how`` "point": at the first point) or line segments (``how`` "segments")."""

    node: Any
    how: str
    slot: Slot | None  # into the pose outputs (None: the fallback point, the first coordinates)
    body: bool = False  # a solid (a ball), not a line or a label: what the camera frames
    reach: float = 0.0  # how far the drawn shape reaches from its points (a ball's radius)

    def place(self, pts: np.ndarray) -> None:
        """Put the node at these points (m, 3)."""
        if self.how == "point":
            self.node.position = tuple(float(v) for v in pts[0])
        else:
            self.node.points = pts.reshape(-1, 2, 3)


@dataclass
class Pen:
    """Draws the shapes of one scene (the main one, or a ghost in one colour) and keeps what
    it made that the poses move: the renderers of :data:`RENDERERS` draw with it."""

    scene: Any
    prefix: str
    ghost: tuple | None = None
    moving: list[Moving] = field(default_factory=list)
    traces: dict[str, tuple[Any, Slot]] = field(default_factory=dict)
    fixed_points: list[np.ndarray] = field(default_factory=list)  # vertices of fixed surfaces (for the bounds)
    extents: list[float] = field(default_factory=list)  # sizes of solid shapes (the camera's sense of scale)
    local: dict[str, list[tuple[np.ndarray, np.ndarray]]] = field(default_factory=dict)  # frame -> its solids' boxes
    grounds: list[tuple[Any, float]] = field(default_factory=list)  # (node, height) of each ground plane
    #: the labels: (node, frame or None, offset on it; or None, None, the index of its Moving)
    labels: list[tuple[Any, str | None, Any]] = field(default_factory=list)

    def solid(self, s: decl.Shape, lo, hi) -> None:
        """A solid on a frame spans the box (lo, hi) in the frame's coordinates (what frames the
        mechanism: :meth:`DeclaredScene.parts_at`)."""
        if s.frame:
            self.local.setdefault(s.frame, []).append((np.asarray(lo, float), np.asarray(hi, float)))

    def path(self, s: decl.Shape) -> str:
        parent = f"{self.prefix}/frames/{s.frame}" if s.frame else f"{self.prefix}/world"
        return f"{parent}/{s.name}"

    def color(self, s: decl.Shape) -> tuple:
        return tuple(s.color) if self.ghost is None else self.ghost

    def style(self, s: decl.Shape) -> dict:
        """The opacity keyword (translucent ghosts; nothing for an opaque shape)."""
        op = s.opacity if self.ghost is None else min(s.opacity, GHOST_OPACITY)
        return {"opacity": op} if op < 1 else {}

    def lines(self, name: str, color: tuple, px: float):
        return self.scene.add_line_segments(
            name, points=np.zeros((1, 2, 3), np.float32), colors=color, thickness=px, thickness_units="screen"
        )


# ------------------------------------------------------------------ one renderer per kind
def _box(pen: Pen, s: decl.Box) -> None:
    size = tuple(float(abs(v)) for v in s.size)
    pen.extents += size
    off = np.asarray(s.offset, float)
    pen.solid(s, off - np.asarray(size) / 2, off + np.asarray(size) / 2)
    pen.scene.add_box(pen.path(s), color=pen.color(s), dimensions=size, position=tuple(s.offset), **pen.style(s))


def _cylinder(pen: Pen, s: decl.Cylinder) -> None:
    pen.extents += [abs(s.radius), abs(s.length)]
    half = np.full(3, abs(s.radius))
    half[np.argmax(np.abs(AXES[s.axis]))] = abs(s.length) / 2
    off = np.asarray(s.offset, float)
    pen.solid(s, off - half, off + half)
    if abs(s.length) <= geo.DISK * abs(s.radius):  # a coin, a wheel: a round rim (geometry.disk_mesh)
        verts, faces = geo.disk_mesh(abs(s.radius), abs(s.length), AXES[s.axis])
        pen.scene.add_mesh_simple(pen.path(s), verts + off, faces, color=pen.color(s), **pen.style(s))
        return
    pen.scene.add_cylinder(
        pen.path(s),
        radius=abs(s.radius),
        height=abs(s.length),
        color=pen.color(s),
        wxyz=axis_wxyz(s.axis),
        position=tuple(s.offset),
        radial_segments=48,
        **pen.style(s),
    )


def _sphere(pen: Pen, s: decl.Sphere) -> None:
    pen.extents.append(abs(s.radius))
    node = pen.scene.add_icosphere(
        pen.path(s), radius=abs(s.radius), color=pen.color(s), position=tuple(s.offset), **pen.style(s)
    )
    if s.at is not None:
        pen.moving.append(Moving(node, "point", s.at, body=True, reach=abs(s.radius)))
    else:
        off = np.asarray(s.offset, float)
        pen.solid(s, off - abs(s.radius), off + abs(s.radius))


def _rod(pen: Pen, s: decl.Rod) -> None:
    p, q = np.asarray(s.start, float), np.asarray(s.end, float)
    length = float(np.linalg.norm(q - p))
    t = abs(s.thickness)
    pen.solid(s, np.minimum(p, q) - t / 2, np.maximum(p, q) + t / 2)
    pen.scene.add_box(
        pen.path(s),
        color=pen.color(s),
        dimensions=(t, t, max(length, 1e-3)),
        position=tuple((p + q) / 2),
        wxyz=geo.quat_z_to(q - p) if length > 0 else (1.0, 0.0, 0.0, 0.0),
        **pen.style(s),
    )


def _segments(pen: Pen, s: decl.Segments) -> None:
    node = pen.lines(pen.path(s), pen.color(s), s.thickness or LINE_PX["segments"])
    pen.moving.append(Moving(node, "segments", s.points))


def _trace(pen: Pen, s: decl.Trace) -> None:
    pen.traces[s.name] = (pen.lines(pen.path(s), pen.color(s), s.thickness or LINE_PX["trace"]), s.point)


def _strip(pen: Pen, s: decl.Strip) -> None:
    path = np.asarray(s.path, float)
    verts, faces = strip_mesh(path, float(s.width), s.axis)
    pen.extents.append(float(np.linalg.norm(path.max(0) - path.min(0))) / 2)
    pen.scene.add_mesh_simple(
        pen.path(s), verts, faces, color=pen.color(s), side="double", cast_shadow=False, **pen.style(s)
    )
    pen.fixed_points.append(verts)


def _label(pen: Pen, s: decl.Label) -> None:
    if pen.ghost is not None:
        return  # one name per part is enough
    if s.at is not None:
        node = pen.scene.add_label(pen.path(s), s.text, anchor="bottom-left")
        pen.labels.append((node, None, len(pen.moving)))
        pen.moving.append(Moving(node, "point", s.at))
    else:  # on a frame (moves with it) or in the world
        node = pen.scene.add_label(pen.path(s), s.text, position=tuple(s.offset), anchor="bottom-left")
        pen.labels.append((node, s.frame, np.asarray(s.offset, float)))


def _ground(pen: Pen, s: decl.Ground, width: float = 200.0, infinite: bool = True) -> None:
    node = pen.scene.add_grid(
        f"{pen.prefix}/ground",
        width=width,
        height=width,
        plane="xy",
        cell_size=0.5,
        section_size=2.0,
        cell_color=(205, 208, 200),
        section_color=(150, 155, 145),
        plane_color=tuple(s.color),
        plane_opacity=GROUND_OPACITY,
        shadow_opacity=0.25,
        infinite_grid=infinite,
        fade_distance=120.0,
        position=(0.0, 0.0, float(s.height)),
    )
    pen.grounds.append((node, float(s.height)))


RENDERERS: dict[type, Callable[[Pen, Any], None]] = {
    decl.Box: _box,
    decl.Cylinder: _cylinder,
    decl.Sphere: _sphere,
    decl.Rod: _rod,
    decl.Segments: _segments,
    decl.Trace: _trace,
    decl.Strip: _strip,
    decl.Label: _label,
    decl.Ground: _ground,
}


def draw(pen: Pen, cv: CompiledVisuals, sizes: np.ndarray) -> None:
    """Every declared shape, by its kind's renderer (a ghost leaves out what does not move)."""
    for cs in cv.shapes:
        if pen.ghost is not None and cs.fixed:
            continue  # drawn once, by the main scene
        shape = cs.resolve(sizes)
        RENDERERS[type(shape)](pen, shape)


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
        self.pen = Pen(scene, self.prefix, ghost)
        self.frames: dict = {}  # frame name -> node
        self.sizes_for: tuple | None = None
        self.frame_poses: dict = {}  # frame name -> (positions (n,3), wxyz (n,4))
        self.points: list[np.ndarray] = []
        self.rows: list[np.ndarray] = []  # per moving node: its points over the run (n, m, 3)
        self.moves: list[bool] = []
        self.shown: int | None = None  # the output row the nodes show
        self.extent = 0.5  # a length of the system itself: its largest shape (m)
        self.bounds_: Bounds | None = None
        self.parts_rows: Bounds | None = None  # per output row, the box of the parts (framing.parts_rows)
        self.centre_rows: np.ndarray = np.zeros((1, 3))  # per output row, the point a following camera follows
        self.tag_node: Any = None  # a label naming a ghost, when it rides on a moving part
        self.tag_rows: np.ndarray | None = None
        self.tag_label: tuple | None = None  # (node, frame, offset on it) or (node, None, its points per row)

    @property
    def moving(self) -> list[Moving]:
        return self.pen.moving

    # ---------------------------------------------------------------- geometry
    def shape(self, params: dict) -> None:
        """(Re)build the shapes for these parameters (sizes may depend on them)."""
        key = tuple(sorted(params.items()))
        if key == self.sizes_for:
            return
        self.sizes_for = key
        self.pen = Pen(self.scene, self.prefix, self.ghost)
        cv = self.compiled
        if cv is None:
            self._fallback()
            return
        for name in cv.frames:
            self.frames[name] = self.scene.add_frame(f"{self.prefix}/frames/{name}", show_axes=False)
        draw(self.pen, cv, cv.sizes(params))
        self.extent = max(self.pen.extents, default=0.5)

    def _fallback(self) -> None:
        """A system without visuals: a ball at its first coordinates (with a ground and its trace)."""
        pen, pre = self.pen, self.prefix
        color = (200, 80, 40) if self.ghost is None else self.ghost
        kw = {} if self.ghost is None else {"opacity": GHOST_OPACITY}
        node = self.scene.add_icosphere(f"{pre}/world/point", radius=0.05, color=color, **kw)
        pen.moving.append(Moving(node, "point", None, body=True, reach=0.05))
        if self.ghost is None:
            _ground(pen, decl.Ground(name="ground"), width=40.0, infinite=False)
            pen.traces["trace"] = (pen.lines(f"{pre}/world/trace", (214, 48, 39), 2.0), Slot(0, (3,)))

    # ---------------------------------------------------------------- poses
    def install(self, run, params: dict) -> None:
        """Poses of every row of a run (and the traces)."""
        self.shown = None
        self.shape(params)
        cv = self.compiled
        frames: dict = {}
        if cv is None:
            names = list(built(self.system).coordinates)[:3]
            cols = [run.state[n] for n in names] + [np.zeros(len(run.t))] * (3 - len(names))
            out = list(_clip(np.column_stack(cols)).T)
            self.frame_poses = {}
        else:
            frames, out = cv.frame_poses(dict(run.state), params)
            self.frame_poses = {k: (_clip(p), rotation_to_wxyz(np.nan_to_num(R))) for k, (p, R) in frames.items()}
        self.points = out
        extremes = [pos for pos, _ in self.frame_poses.values()]
        for node, slot in self.pen.traces.values():
            pts = _clip(slot.rows(out))
            node.points = geo.segments(pts[geo.decimate(len(pts), 2000)])
            extremes.append(pts)
        extremes += self._install_moving(out)
        if not extremes:  # nothing moves: the fixed surfaces then
            extremes += self.pen.fixed_points
        if extremes:
            self.bounds_ = (np.min([e.min(0) for e in extremes], axis=0), np.max([e.max(0) for e in extremes], axis=0))
        movers = [(m, rows) for m, rows, moves in zip(self.pen.moving, self.rows, self.moves, strict=True) if moves]
        self.parts_rows = framing.parts_rows(frames, self.pen.local, movers, len(run.t))
        self.centre_rows = framing.centre_rows(self.frame_poses, self.rows, len(run.t))
        self._see_through_ground()

    def _see_through_ground(self) -> None:
        """A ground plane that a part of this run goes well below (a load falling through a hole,
        more than half the system's size: not a turned wheel's box grazing it) is drawn nearly
        clear, so that what is under it stays in view; else as declared."""
        motion = self.parts_motion()
        lowest = np.inf if motion is None else float(motion[0][2])
        for node, height in self.pen.grounds:
            below = lowest < height - 0.5 * self.extent
            node.plane_opacity = GROUND_SEEN_THROUGH if below else GROUND_OPACITY

    def label_points(self, k: int | None = None) -> list[tuple[Any, np.ndarray]]:
        """The labels at output row k (default: the row shown) with their world points
        (:mod:`web.labels` keeps them apart on the screen), and a ghost's tag."""
        k = (self.shown or 0) if k is None else k
        labels = [*self.pen.labels, *([self.tag_label] if self.tag_label is not None else [])]
        points = [(node, self._world_point(frame, where, k)) for node, frame, where in labels]
        return [(node, p) for node, p in points if p is not None]

    def _world_point(self, frame: str | None, where, k: int) -> np.ndarray | None:
        """Where a label is at output row k: ``where`` on ``frame`` (an offset), or in the world
        (a point, points per row, or the index of the :class:`Moving` that places it)."""
        if frame is not None:
            if frame not in self.frame_poses:
                return None
            pos, q = self.frame_poses[frame]
            i = min(k, len(pos) - 1)
            return pos[i] + geo.rotate(q[i], where)
        if isinstance(where, int):  # placed by a Moving: its first point
            if where >= len(self.rows):
                return None
            where = self.rows[where][:, 0]
        where = np.asarray(where, float)
        return where[min(k, len(where) - 1)] if where.ndim == 2 else where

    def parts_at(self, k: int) -> Bounds | None:
        """(lowest, highest) corner of the mechanism's parts at output row k
        (:func:`framing.parts_rows`)."""
        if self.parts_rows is None:
            return None
        lo, hi = self.parts_rows
        k = min(max(k, 0), len(lo) - 1)
        return lo[k].copy(), hi[k].copy()

    def centre_at(self, k: int) -> np.ndarray:
        """The point a following camera follows at output row k (:func:`framing.centre_rows`)."""
        return self.centre_rows[min(max(k, 0), len(self.centre_rows) - 1)].astype(float)

    def parts_envelope(self) -> Bounds | None:
        """(lowest, highest) corner of everything the parts do around the point a following
        camera follows, over the whole run (a load falling from its pulley, a frame turning
        about its centre): framed around that point, they are in view at every time.  A small
        part moving over a large fixed surface is framed with some of it (:func:`framing.at_least`)."""
        if self.parts_rows is None:
            return None
        lo, hi = self.parts_rows
        c = self.centre_rows
        return framing.at_least((lo - c).min(axis=0), (hi - c).max(axis=0), self.extent)

    def mechanism_at(self, k: int) -> Bounds | None:
        """What *Fit view* frames at output row k: the parts' box (:meth:`parts_at`), at least a
        share of the system's own size (:func:`framing.at_least`)."""
        box = self.parts_at(k)
        return None if box is None else framing.at_least(*box, self.extent)

    def parts_motion(self) -> Bounds | None:
        """(lowest, highest) corner of the mechanism's parts over the whole run (not the traces
        their points leave): a first view fixed on it shows the whole motion."""
        if self.parts_rows is None:
            return None
        lo, hi = self.parts_rows
        return lo.min(axis=0), hi.max(axis=0)

    def _install_moving(self, out: list[np.ndarray]) -> list[np.ndarray]:
        """Each moving node's points over the run; one that does not move is placed once
        (a ghost does not show it: the main scene does).  Returns the points of those that
        move (for the bounds)."""
        self.rows, self.moves = [], []
        for m in self.pen.moving:
            slot = m.slot or Slot(0, (3,))
            pts = _clip(slot.rows(out)).reshape(len(out[0]), -1, 3).astype(np.float32)
            moves = bool(np.any(pts != pts[:1]))
            self.rows.append(pts)
            self.moves.append(moves)
            if not moves:
                m.place(pts[0])
                m.node.visible = self.ghost is None
        return [r.reshape(-1, 3) for r, moves in zip(self.rows, self.moves, strict=True) if moves]

    def pose(self, k: int) -> None:
        """Put every node at output row k (nothing is sent when row k is already shown)."""
        if k == self.shown:
            return
        prev, self.shown = self.shown, k
        for name, (pos, q) in self.frame_poses.items():
            node = self.frames[name]
            node.position = tuple(pos[k])
            node.wxyz = tuple(q[k])
        for m, rows, moves in zip(self.pen.moving, self.rows, self.moves, strict=True):
            if moves and (prev is None or not np.array_equal(rows[k], rows[prev])):
                m.place(rows[k])
        if self.tag_node is not None and self.tag_rows is not None:
            self.tag_node.position = tuple(self.tag_rows[min(k, len(self.tag_rows) - 1)])

    def tag(self, text: str, row: int = 1, spacing: float = 0.1) -> None:
        """A label naming this scene (a ghost's run), riding above its first frame or above
        its first moving part (call after :meth:`install`); ghosts in one place put their
        labels in rows (``row`` 1, 2, …, ``spacing`` apart) so that they do not overlap."""
        above = np.array([0.0, 0.0, 1.3 * self.extent + 0.1 + spacing * (row - 1)])
        if self.frame_poses:
            first = next(iter(self.frame_poses))
            path = f"{self.prefix}/frames/{first}/tag"
            node = self.scene.add_label(path, text, position=tuple(above), anchor="bottom-left")
            self.tag_label = (node, first, above)
        elif self.rows:
            self.tag_node = self.scene.add_label(f"{self.prefix}/world/tag", text, anchor="bottom-left")
            self.tag_rows = self.rows[0][:, 0].astype(float) + above
            self.tag_label = (self.tag_node, None, self.tag_rows)
            self.shown = None

    def bounds(self) -> Bounds | None:
        """(lowest, highest) corner of everything that moves over the installed run (the
        paths travelled; fixed surfaces only when nothing moves)."""
        return self.bounds_

    def part_names(self) -> list[str]:
        """The scene nodes of the system's moving parts: the solids on its frames, and the balls
        and line segments placed at points that move with the state (not the ground, traces,
        labels or fixed shapes).  What its first view must show (the browser test projects them)."""
        names = []
        if self.compiled is not None:
            solids = {"box", "cylinder", "sphere", "rod"}
            names += [
                f"{self.prefix}/frames/{cs.frame}/{cs.name}"
                for cs in self.compiled.shapes
                if cs.frame is not None and cs.kind in solids
            ]
        for m, moves in zip(self.pen.moving, self.moves, strict=False):
            if moves and (m.body or m.how == "segments"):
                names.append(m.node.name)
        return names


def strip_mesh(path: np.ndarray, width: float, axis: str) -> tuple[np.ndarray, np.ndarray]:
    """A polyline (n, 3) swept by ``width`` along ``axis`` (centred): (vertices, faces)."""
    d = np.array(AXES[axis]) * width / 2
    n = len(path)
    verts = np.vstack([path - d, path + d]).astype(np.float32)
    faces = [(i, i + 1, n + i) for i in range(n - 1)] + [(i + 1, n + i + 1, n + i) for i in range(n - 1)]
    return verts, np.array(faces, np.uint32)
