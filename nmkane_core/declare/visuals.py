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

:func:`compile_visuals` turns the declaration into :class:`CompiledVisuals`: the shape
list (JSON-able data) and generated numpy source with two functions, ``sizes(p)`` and
``poses(s, p)`` (``s``: state name → array over rows, so a whole trajectory is evaluated
at once).  The source is cached on disk under ``<cache root>/visuals/`` keyed by the
system's :meth:`~nmkane_core.declare.system.System.kernel_key` and the file defining the visuals,
so a later process loads it without sympy.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    "CompiledVisuals",
    "Frame",
    "Shape",
    "Visuals",
    "box",
    "compile_visuals",
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

GENERATOR_VERSION = "2"
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


# --------------------------------------------------------------------------- compiled form
@dataclass
class CompiledVisuals:
    """Numeric pose functions of a system's visuals (no sympy).

    ``shapes``: one dict per shape (kind, name, frame, axis, color, opacity, thickness, and
    index ranges into the outputs of ``sizes`` — size, offset, end, path — and of ``poses``
    — points); ``frames``: frame name → index of
    its 12 pose outputs (origin, then the rotation row by row)."""

    shapes: list[dict]
    frames: dict[str, int]
    source: str
    view: tuple | None = None  # direction system → default camera (see Visuals.view)
    _ns: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        exec(compile(self.source, "<nmkane visuals>", "exec"), self._ns)

    def sizes(self, params: dict) -> np.ndarray:
        """The parameter-only numbers (sizes, offsets, ground height) for these parameters."""
        return np.array([float(v) for v in self._ns["sizes"](params)], float)

    def poses(self, states: dict, params: dict) -> list[np.ndarray]:
        """Every pose output over the rows of ``states`` (name → array), each of shape (n,)."""
        n = len(next(iter(states.values())))
        with np.errstate(all="ignore"):
            out = self._ns["poses"]({k: np.asarray(v, float) for k, v in states.items()}, params)
        return [np.broadcast_to(np.asarray(v, float), (n,)) for v in out]

    def frame_poses(self, states: dict, params: dict) -> tuple[dict, list[np.ndarray]]:
        """(frame name → (origins (n, 3), rotations (n, 3, 3)), all pose outputs)."""
        out = self.poses(states, params)
        frames = {}
        for name, i in self.frames.items():
            pos = np.stack(out[i : i + 3], axis=1)
            rot = np.stack(out[i + 3 : i + 12], axis=1).reshape(-1, 3, 3)
            frames[name] = (pos, rot)
        return frames, out

    def point(self, out: list[np.ndarray], index: int) -> np.ndarray:
        """World point (n, 3) starting at pose output ``index``."""
        return np.stack(out[index : index + 3], axis=1)


def _plain(expr, names: set[str]):
    """sympy expression with dynamicsymbols (x(t)) replaced by plain symbols named alike."""
    import sympy as sp

    expr = sp.sympify(expr)
    funcs = {
        f: sp.Symbol(f.func.__name__, real=True)
        for f in expr.atoms(sp.Function)
        if isinstance(f, sp.core.function.AppliedUndef)
    }
    if funcs:
        expr = expr.subs(funcs)
    return expr.subs({s: sp.Symbol(s.name, real=True) for s in expr.free_symbols if s.name in names})


def _generate(vis: Visuals, state_names: Sequence[str], param_names: Sequence[str]) -> tuple[list, dict, str]:
    """The shape table, frame index and numpy source of a declaration (sympy)."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    from ..errors import InputError

    names = set(state_names) | set(param_names)
    size_exprs: list = []
    pose_exprs: list = []
    frames: dict = {}
    shapes: list = []

    def add(target, exprs, where, allowed):
        start = len(target)
        for e in exprs:
            e = _plain(e, names)
            bad = sorted(s.name for s in e.free_symbols if s.name not in allowed)
            if bad:
                raise InputError(
                    where,
                    bad[0],
                    "names of " + ("parameters" if allowed is param_set else "coordinates, speeds and parameters"),
                    "unknown name",
                )
            target.append(e)
        return start

    param_set = set(param_names)
    for f in vis.frames:
        rot = sp.eye(3) if f.rotation is None else sp.Matrix(f.rotation)
        if rot.shape != (3, 3) or len(tuple(f.origin)) != 3:
            raise InputError(f"visuals.{f.name}", f.name, "origin of 3 expressions and a 3×3 rotation", "bad shape")
        frames[f.name] = add(pose_exprs, list(f.origin) + list(rot), f"visuals.{f.name}", names)
    for s in vis.shapes:
        d = {
            "kind": s.kind,
            "name": s.name,
            "frame": s.frame,
            "axis": s.axis,
            "color": list(s.color),
            "opacity": float(s.opacity),
            "thickness": float(s.thickness),
            "text": s.text,
        }
        d["size"] = [add(size_exprs, s.size, f"visuals.{s.name}.size", param_set), len(s.size)]
        d["offset"] = add(size_exprs, s.offset, f"visuals.{s.name}.offset", param_set)
        d["end"] = add(size_exprs, s.end, f"visuals.{s.name}.end", param_set) if s.end else None
        d["path"] = [add(size_exprs, p, f"visuals.{s.name}.path", param_set) for p in s.path]
        d["points"] = [add(pose_exprs, p, f"visuals.{s.name}.points", names) for p in s.points]
        shapes.append(d)

    printer = NumPyPrinter({"fully_qualified_modules": True})

    def body(exprs, fn, arg_lines):
        lines = [f"def {fn}({'s, p' if fn == 'poses' else 'p'}):", *arg_lines]
        subs, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_c"))
        for sym, e in subs:
            lines.append(f"    {sym} = {printer.doprint(e)}")
        lines.append("    return [" + ", ".join(printer.doprint(e) for e in reduced) + "]")
        return lines

    def unpack(exprs, with_state):
        used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        out = []
        for sname in sorted(s.name for s in used):
            src = "s" if with_state and sname in state_names else "p"
            out.append(f"    {_ident(sname)} = {src}[{sname!r}]")
        return out

    def ident_subs(exprs):
        return [e.subs({s: sp.Symbol(_ident(s.name), real=True) for s in e.free_symbols}) for e in exprs]

    src = ["import functools", "import numpy", "", ""]
    src += [*body(ident_subs(size_exprs), "sizes", unpack(size_exprs, False)), "", ""]
    src += [*body(ident_subs(pose_exprs), "poses", unpack(pose_exprs, True)), ""]
    return shapes, frames, "\n".join(src)


def _ident(name: str) -> str:
    return "v_" + "".join(c if c.isalnum() else "_" for c in name)


_MEMO: dict = {}
_LOCK = threading.Lock()


def compile_visuals(system) -> CompiledVisuals | None:
    """A system's compiled visuals (None if it declares none): from memory, the disk cache,
    or generated (sympy) and cached.  ``system`` is a :class:`~nmkane_core.declare.system.System`."""
    if getattr(system, "visuals", None) is None:
        return None
    with _LOCK:
        memo = _MEMO.get(id(system))
        if memo is not None and memo[0] is system:
            return memo[1]
    from ..kernel.cache import declared_data

    def build() -> dict:
        from ..errors import InputError

        vis = system.visuals()
        if not isinstance(vis, Visuals):
            raise InputError(
                f"{system.name}: visuals", type(vis).__name__, "a function returning Visuals", "not Visuals"
            )
        info = system.info(system.default_variant)
        state_names = tuple(info.q) + tuple(info.u) + tuple(info.outputs)
        shapes, frames, source = _generate(vis, state_names, system.param_names)
        view = None if vis.view is None else [float(c) for c in vis.view]
        return {"shapes": shapes, "frames": frames, "source": source, "view": view}

    data = declared_data(system, system.visuals, "visuals", __file__, GENERATOR_VERSION, build)
    view = data.get("view")
    compiled = CompiledVisuals(data["shapes"], data["frames"], data["source"], None if view is None else tuple(view))
    with _LOCK:
        _MEMO[id(system)] = (system, compiled)
    return compiled


def rotation_to_wxyz(R: np.ndarray) -> np.ndarray:
    """Unit quaternions (n, 4) of rotation matrices (n, 3, 3) (vectorized Shepperd's method)."""
    R = np.asarray(R, float).reshape(-1, 3, 3)
    n = len(R)
    q = np.zeros((n, 4))
    tr = R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2]
    cands = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(cands, axis=1)
    for case in range(4):
        m = k == case
        if not m.any():
            continue
        r = R[m]
        if case == 0:
            s = np.sqrt(np.maximum(1 + tr[m], 1e-300)) * 2
            q[m] = np.stack(
                [s / 4, (r[:, 2, 1] - r[:, 1, 2]) / s, (r[:, 0, 2] - r[:, 2, 0]) / s, (r[:, 1, 0] - r[:, 0, 1]) / s],
                axis=1,
            )
        else:
            i = case - 1
            j, l = (i + 1) % 3, (i + 2) % 3
            s = np.sqrt(np.maximum(1 + r[:, i, i] - r[:, j, j] - r[:, l, l], 1e-300)) * 2
            comp = np.zeros((m.sum(), 4))
            comp[:, 0] = (r[:, l, j] - r[:, j, l]) / s
            comp[:, 1 + i] = s / 4
            comp[:, 1 + j] = (r[:, j, i] + r[:, i, j]) / s
            comp[:, 1 + l] = (r[:, l, i] + r[:, i, l]) / s
            q[m] = comp
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return np.nan_to_num(q, nan=0.0) + np.where(np.isfinite(q).all(axis=1, keepdims=True), 0.0, [1, 0, 0, 0])


def axis_wxyz(axis: str) -> tuple[float, float, float, float]:
    """The constant rotation turning +z (viser's cylinder axis) onto the frame's ``axis``."""
    if axis == "x":
        return (math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0)
    if axis == "y":
        return (math.cos(-math.pi / 4), math.sin(-math.pi / 4), 0.0, 0.0)
    return (1.0, 0.0, 0.0, 0.0)
