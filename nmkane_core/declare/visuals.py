"""What a system looks like, declared with it: shapes on frames and points given as sympy
expressions of the coordinates and parameters, compiled once into numpy pose functions.

A system declares ``System(visuals=fn)`` where ``fn()`` (sympy inside: called only when
the pose functions are not cached yet) returns a :class:`Visuals`:

* :class:`Frame` ``(name, origin, rotation)`` — origin a 3-vector and rotation a 3×3
  matrix (body axes in world coordinates, columns) of the state names and parameters
  (plain symbols or ``dynamicsymbols``; :func:`rot_x`, :func:`rot_y`, :func:`rot_z` or
  ``N.dcm(B)`` build rotations), or ``Frame.of(name, B, P, N, O)`` from a
  sympy.physics.mechanics ReferenceFrame ``B`` and Point ``P`` (``N``, ``O``: the ground);
* shapes attached to a frame (``frame=None``: the world) — :func:`box`, :func:`cylinder`
  (a disk is a short one), :func:`sphere`; sizes and offsets are expressions of the
  parameters only;
* :func:`rod` — a square bar between two points of a frame (a member of a frame, a leg, an
  axle), endpoints expressions of the parameters;
* shapes given by world points — :func:`sphere` with ``at=``, :func:`segments` (line
  segments between points, e.g. a spoke), :func:`polyline` (a thread over pulleys),
  :func:`trace` (the path of a point);
* :func:`strip` — a fixed curved surface: a polyline of parameter expressions swept across
  a width (a guide, a ramp, a bowl's cross-section);
* :func:`ground` — a grid plane at a height;
* :func:`label` — a text at a world point ("load P").

Each builder returns one small class per kind (:class:`Box`, :class:`Cylinder`,
:class:`Sphere`, :class:`Rod`, :class:`Segments`, :class:`Trace`, :class:`Strip`,
:class:`Label`, :class:`Ground`; :data:`SHAPES` maps kind names to them): its fields are
the one definition of what the kind holds, which of them are expressions of the
parameters only and which move with the state — the compiler and the web view read them.

``Visuals(view=(dx, dy, dz))`` says from which side a viewer's default camera looks at
the system (the direction from the system to the camera; None: the viewer's choice).

What is drawn is compiled into numpy pose functions by :mod:`nmkane_core.kernel.visuals`
(:func:`~nmkane_core.kernel.visuals.compile_visuals`), once per system, cached on disk.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, fields
from typing import Any, ClassVar

__all__ = [
    "Frame",
    "Shape",
    "SHAPES",
    "Box",
    "Cylinder",
    "Ground",
    "Label",
    "Rod",
    "Segments",
    "Sphere",
    "Strip",
    "Trace",
    "Visuals",
    "box",
    "cylinder",
    "ground",
    "label",
    "polyline",
    "rod",
    "rot_x",
    "rot_y",
    "rot_z",
    "segments",
    "sphere",
    "strip",
    "trace",
]

AXES = {"x": (1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "z": (0.0, 0.0, 1.0)}


@dataclass(frozen=True)
class Frame:
    """A moving frame: ``origin`` (3 expressions) and ``rotation`` (3×3, body axes as
    columns in world coordinates; None: not rotated)."""

    name: str
    origin: Any
    rotation: Any = None

    @classmethod
    def of(cls, name: str, frame, point, inertial, origin) -> Frame:
        """From sympy.physics.mechanics: the ReferenceFrame ``frame`` placed at the Point
        ``point``, both seen from the ``inertial`` frame and its fixed Point ``origin``."""
        return cls(name, tuple(point.pos_from(origin).to_matrix(inertial)), inertial.dcm(frame))


@dataclass(frozen=True, kw_only=True)
class Shape:
    """One drawn thing: the fields every kind has.  Each kind is a subclass naming which of
    its fields hold expressions of the parameters only (``PARAM_FIELDS``: sizes, offsets,
    fixed paths; evaluated once per parameter set) and which hold world points that move
    with the state (``STATE_FIELDS``; evaluated on every output row); its other fields are
    plain values (colours, an axis name, a text).  The same class describes the shape
    declared (its fields sympy expressions) and the shape resolved for drawing (its
    parameter fields numbers, see :meth:`nmkane_core.kernel.visuals.CompiledShape.resolve`)."""

    kind: ClassVar[str] = ""
    PARAM_FIELDS: ClassVar[tuple[str, ...]] = ()
    STATE_FIELDS: ClassVar[tuple[str, ...]] = ()

    name: str
    frame: str | None = None  # the frame it is attached to (None: the world)
    color: tuple = (120, 130, 150)
    opacity: float = 1.0

    @classmethod
    def plain_fields(cls) -> tuple[str, ...]:
        """The fields that are plain values (neither expressions nor name and frame)."""
        skip = {"name", "frame", *cls.PARAM_FIELDS, *cls.STATE_FIELDS}
        return tuple(f.name for f in fields(cls) if f.name not in skip)


@dataclass(frozen=True, kw_only=True)
class Box(Shape):
    """A box of edge lengths ``size`` (lx, ly, lz) centred at ``offset`` in its frame."""

    kind = "box"
    PARAM_FIELDS = ("size", "offset")
    size: Any = (1, 1, 1)
    offset: Any = (0, 0, 0)


@dataclass(frozen=True, kw_only=True)
class Cylinder(Shape):
    """A cylinder (a disk when short) along ``axis`` (x|y|z) of its frame, centred at ``offset``."""

    kind = "cylinder"
    PARAM_FIELDS = ("radius", "length", "offset")
    radius: Any = 1
    length: Any = 1
    offset: Any = (0, 0, 0)
    axis: str = "z"


@dataclass(frozen=True, kw_only=True)
class Sphere(Shape):
    """A ball at ``offset`` in its frame, or at the world point ``at`` (None: on the frame)."""

    kind = "sphere"
    PARAM_FIELDS = ("radius", "offset")
    STATE_FIELDS = ("at",)
    radius: Any = 1
    offset: Any = (0, 0, 0)
    at: Any = None
    color: tuple = (200, 80, 40)


@dataclass(frozen=True, kw_only=True)
class Rod(Shape):
    """A square bar of side ``thickness`` from ``start`` to ``end`` (points of its frame)."""

    kind = "rod"
    PARAM_FIELDS = ("start", "end", "thickness")
    start: Any = (0, 0, 0)
    end: Any = (0, 0, 1)
    thickness: Any = 0.05
    color: tuple = (150, 160, 178)


@dataclass(frozen=True, kw_only=True)
class Segments(Shape):
    """Line segments between world points: ``points`` = (p0, q0, p1, q1, …); ``thickness``
    in screen pixels (0: the viewer's default)."""

    kind = "segments"
    STATE_FIELDS = ("points",)
    points: Any = ()
    thickness: float = 0.0
    color: tuple = (90, 40, 30)


@dataclass(frozen=True, kw_only=True)
class Trace(Shape):
    """The path of the world ``point`` over the run; ``thickness`` in screen pixels."""

    kind = "trace"
    STATE_FIELDS = ("point",)
    point: Any = (0, 0, 0)
    thickness: float = 0.0
    color: tuple = (214, 48, 39)


@dataclass(frozen=True, kw_only=True)
class Strip(Shape):
    """A fixed surface: the polyline ``path`` (world points) swept by ``width`` along ``axis``."""

    kind = "strip"
    PARAM_FIELDS = ("path", "width")
    path: Any = ()
    width: Any = 1
    axis: str = "y"
    color: tuple = (175, 188, 205)
    opacity: float = 0.65


@dataclass(frozen=True, kw_only=True)
class Label(Shape):
    """A text at the world point ``at``, or at ``offset`` in its frame (``at`` None)."""

    kind = "label"
    PARAM_FIELDS = ("offset",)
    STATE_FIELDS = ("at",)
    text: str = ""
    offset: Any = (0, 0, 0)
    at: Any = None


@dataclass(frozen=True, kw_only=True)
class Ground(Shape):
    """The plane z = ``height``, drawn as a grid."""

    kind = "ground"
    PARAM_FIELDS = ("height",)
    height: Any = 0
    color: tuple = (232, 236, 226)


SHAPES: dict[str, type[Shape]] = {
    c.kind: c for c in (Box, Cylinder, Sphere, Rod, Segments, Trace, Strip, Label, Ground)
}


@dataclass(frozen=True)
class Visuals:
    """A system's visual declaration: frames and shapes (see the module's docstring);
    ``view``: the direction from the system to a viewer's default camera (None: any)."""

    frames: tuple = ()
    shapes: tuple = ()
    view: tuple | None = None

    def __post_init__(self):
        from ..errors import InputError

        if self.view is not None:
            v = tuple(float(c) for c in self.view)
            if len(v) != 3 or not all(math.isfinite(c) for c in v) or not any(v):
                raise InputError("visuals.view", self.view, "three finite numbers, not all zero", "bad direction")
        names = {f.name for f in self.frames}
        for s in self.shapes:
            if s.frame is not None and s.frame not in names:
                raise InputError(
                    f"visuals.{s.name}.frame", s.frame, " | ".join(sorted(names)) or "no frames", "not a declared frame"
                )


def _refuse(where: str, value, allowed: str, why: str):
    from ..errors import InputError

    raise InputError(where, value, allowed, why)


def box(name, frame, size, offset=(0, 0, 0), color=(120, 130, 150), opacity=1.0) -> Shape:
    return Box(name=name, frame=frame, size=tuple(size), offset=tuple(offset), color=tuple(color), opacity=opacity)


def cylinder(name, frame, radius, length, axis="z", offset=(0, 0, 0), color=(120, 130, 150), opacity=1.0) -> Shape:
    """A cylinder (a disk when short) along ``axis`` of its frame, centred at ``offset``."""
    if axis not in AXES:
        _refuse(f"visuals.{name}.axis", axis, "x | y | z", "unknown axis")
    return Cylinder(
        name=name,
        frame=frame,
        radius=radius,
        length=length,
        axis=axis,
        offset=tuple(offset),
        color=tuple(color),
        opacity=opacity,
    )


def sphere(name, radius, frame=None, offset=(0, 0, 0), at=None, color=(200, 80, 40), opacity=1.0) -> Shape:
    """A ball on a frame (at ``offset``) or at a world point ``at``."""
    return Sphere(
        name=name,
        frame=frame,
        radius=radius,
        offset=tuple(offset),
        at=tuple(at) if at is not None else None,
        color=tuple(color),
        opacity=opacity,
    )


def rod(name, frame, start, end, thickness, color=(150, 160, 178), opacity=1.0) -> Shape:
    """A square bar of side ``thickness`` from ``start`` to ``end`` (points of its frame,
    expressions of the parameters)."""
    if len(tuple(start)) != 3 or len(tuple(end)) != 3:
        _refuse(f"visuals.{name}", (start, end), "two points of 3 expressions", "bad shape")
    return Rod(
        name=name,
        frame=frame,
        start=tuple(start),
        end=tuple(end),
        thickness=thickness,
        color=tuple(color),
        opacity=opacity,
    )


def segments(name, pairs, color=(90, 40, 30), thickness=0.0) -> Shape:
    """Line segments between world points: ``pairs`` = [(p, q), ...]; ``thickness`` in pixels."""
    pts = tuple(tuple(p) for pq in pairs for p in pq)
    return Segments(name=name, points=pts, color=tuple(color), thickness=float(thickness))


def polyline(name, points, color=(90, 40, 30), thickness=0.0) -> Shape:
    """A path through world points (a thread over pulleys): segments between neighbours."""
    pts = [tuple(p) for p in points]
    if len(pts) < 2:
        _refuse(f"visuals.{name}", len(pts), "at least 2 points", "too few points")
    return segments(name, list(itertools.pairwise(pts)), color, thickness)


def trace(name, point, color=(214, 48, 39), thickness=0.0) -> Shape:
    """The path of a world point over the run."""
    return Trace(name=name, point=tuple(point), color=tuple(color), thickness=float(thickness))


def strip(name, path, width, axis="y", color=(175, 188, 205), opacity=0.65) -> Shape:
    """A fixed surface: the polyline ``path`` (world points, expressions of the parameters)
    swept by ``width`` along ``axis`` (x|y|z), centred on the path."""
    pts = tuple(tuple(p) for p in path)
    if axis not in AXES or len(pts) < 2:
        _refuse(f"visuals.{name}", (axis, len(pts)), "axis x | y | z and at least 2 points", "bad strip")
    return Strip(name=name, path=pts, width=width, axis=axis, color=tuple(color), opacity=opacity)


def label(name, text, at=None, frame=None, offset=(0, 0, 0)) -> Shape:
    """A text naming a part: at a world point ``at``, or at ``offset`` in ``frame`` (cheaper
    to draw: it moves with its frame)."""
    if (at is None) == (frame is None):
        _refuse(f"visuals.{name}", (at, frame), "either a world point at= or a frame=", "where?")
    if at is not None:
        return Label(name=name, at=tuple(at), text=str(text))
    return Label(name=name, frame=frame, offset=tuple(offset), text=str(text))


def ground(height=0, color=(232, 236, 226)) -> Shape:
    """The plane z = height, drawn as a grid."""
    return Ground(name="ground", height=height, color=tuple(color))


def rot_x(a):
    import sympy as sp

    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def rot_y(a):
    import sympy as sp

    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def rot_z(a):
    import sympy as sp

    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])
