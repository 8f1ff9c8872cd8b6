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

``Visuals(view=(dx, dy, dz))`` says from which side a viewer's default camera looks at
the system (the direction from the system to the camera; None: the viewer's choice).

What is drawn is compiled into numpy pose functions by :mod:`nmkane_core.kernel.visuals`
(:func:`~nmkane_core.kernel.visuals.compile_visuals`), once per system, cached on disk.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from typing import Any

__all__ = [
    "Frame",
    "Shape",
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


@dataclass(frozen=True)
class Shape:
    """One drawn thing.  ``kind``: box | cylinder | sphere | rod | segments | trace | strip | ground | label.
    ``size``: box (lx, ly, lz), cylinder (radius, length), sphere (radius,), rod (thickness,),
    strip (width,), ground (height,); ``offset``: position in its frame (a rod's start);
    ``end``: a rod's end in its frame; ``axis``: a cylinder's axis in its frame, a strip's
    sweep direction (x|y|z); ``points``: world points (sphere ``at``, trace point, segment end
    points); ``path``: a strip's polyline (parameter expressions); ``thickness``: of lines,
    in screen pixels (0: the viewer's default); ``text``: a label's text."""

    kind: str
    name: str
    frame: str | None = None
    size: tuple = ()
    offset: tuple = (0, 0, 0)
    axis: str = "z"
    points: tuple = ()
    color: tuple = (120, 130, 150)
    opacity: float = 1.0
    end: tuple = ()
    path: tuple = ()
    thickness: float = 0.0
    text: str = ""


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


def box(name, frame, size, offset=(0, 0, 0), color=(120, 130, 150), opacity=1.0) -> Shape:
    return Shape("box", name, frame, tuple(size), tuple(offset), color=tuple(color), opacity=opacity)


def cylinder(name, frame, radius, length, axis="z", offset=(0, 0, 0), color=(120, 130, 150), opacity=1.0) -> Shape:
    """A cylinder (a disk when short) along ``axis`` of its frame, centred at ``offset``."""
    if axis not in AXES:
        from ..errors import InputError

        raise InputError(f"visuals.{name}.axis", axis, "x | y | z", "unknown axis")
    return Shape("cylinder", name, frame, (radius, length), tuple(offset), axis, color=tuple(color), opacity=opacity)


def sphere(name, radius, frame=None, offset=(0, 0, 0), at=None, color=(200, 80, 40), opacity=1.0) -> Shape:
    """A ball on a frame (at ``offset``) or at a world point ``at``."""
    return Shape(
        "sphere",
        name,
        frame,
        (radius,),
        tuple(offset),
        points=(tuple(at),) if at is not None else (),
        color=tuple(color),
        opacity=opacity,
    )


def rod(name, frame, start, end, thickness, color=(150, 160, 178), opacity=1.0) -> Shape:
    """A square bar of side ``thickness`` from ``start`` to ``end`` (points of its frame,
    expressions of the parameters)."""
    if len(tuple(start)) != 3 or len(tuple(end)) != 3:
        from ..errors import InputError

        raise InputError(f"visuals.{name}", (start, end), "two points of 3 expressions", "bad shape")
    return Shape("rod", name, frame, (thickness,), tuple(start), end=tuple(end), color=tuple(color), opacity=opacity)


def segments(name, pairs, color=(90, 40, 30), thickness=0.0) -> Shape:
    """Line segments between world points: ``pairs`` = [(p, q), ...]; ``thickness`` in pixels."""
    pts = tuple(tuple(p) for pq in pairs for p in pq)
    return Shape("segments", name, points=pts, color=tuple(color), thickness=float(thickness))


def polyline(name, points, color=(90, 40, 30), thickness=0.0) -> Shape:
    """A path through world points (a thread over pulleys): segments between neighbours."""
    pts = [tuple(p) for p in points]
    if len(pts) < 2:
        from ..errors import InputError

        raise InputError(f"visuals.{name}", len(pts), "at least 2 points", "too few points")
    return segments(name, list(itertools.pairwise(pts)), color, thickness)


def trace(name, point, color=(214, 48, 39), thickness=0.0) -> Shape:
    """The path of a world point over the run."""
    return Shape("trace", name, points=(tuple(point),), color=tuple(color), thickness=float(thickness))


def strip(name, path, width, axis="y", color=(175, 188, 205), opacity=0.65) -> Shape:
    """A fixed surface: the polyline ``path`` (world points, expressions of the parameters)
    swept by ``width`` along ``axis`` (x|y|z), centred on the path."""
    pts = tuple(tuple(p) for p in path)
    if axis not in AXES or len(pts) < 2:
        from ..errors import InputError

        raise InputError(f"visuals.{name}", (axis, len(pts)), "axis x | y | z and at least 2 points", "bad strip")
    return Shape("strip", name, None, (width,), axis=axis, path=pts, color=tuple(color), opacity=opacity)


def label(name, text, at=None, frame=None, offset=(0, 0, 0)) -> Shape:
    """A text naming a part: at a world point ``at``, or at ``offset`` in ``frame`` (cheaper
    to draw: it moves with its frame)."""
    if (at is None) == (frame is None):
        from ..errors import InputError

        raise InputError(f"visuals.{name}", (at, frame), "either a world point at= or a frame=", "where?")
    if at is not None:
        return Shape("label", name, points=(tuple(at),), text=str(text))
    return Shape("label", name, frame, offset=tuple(offset), text=str(text))


def ground(height=0, color=(232, 236, 226)) -> Shape:
    """The plane z = height, drawn as a grid."""
    return Shape("ground", "ground", size=(height,), color=tuple(color))


def rot_x(a):
    import sympy as sp

    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def rot_y(a):
    import sympy as sp

    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def rot_z(a):
    import sympy as sp

    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])
