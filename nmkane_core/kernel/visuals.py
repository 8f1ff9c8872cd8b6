"""A system's declared visuals (:mod:`nmkane_core.declare.visuals`) compiled into numpy pose functions.

:func:`compile_visuals` turns the declaration into :class:`CompiledVisuals`: the shape
list (JSON-able data) and generated numpy source with two functions, ``sizes(p)`` and
``poses(s, p)`` (``s``: state name → array over rows, so a whole trajectory is evaluated
at once).  The source is cached on disk under ``<cache root>/visuals/`` keyed by the
system's kernel key (:meth:`nmkane_core.kernel.built.Built.key`) and the file defining the visuals,
so a later process loads it without sympy.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..declare.visuals import AXES, Visuals
from ..errors import InputError
from .built import built
from .cache import declared_data

__all__ = ["AXES", "CompiledVisuals", "axis_wxyz", "compile_visuals", "rotation_to_wxyz"]

GENERATOR_VERSION = "2"


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

    def build() -> dict:
        vis = system.visuals()
        if not isinstance(vis, Visuals):
            raise InputError(
                f"{system.name}: visuals", type(vis).__name__, "a function returning Visuals", "not Visuals"
            )
        info = built(system).info(system.default_variant)
        state_names = tuple(info.q) + tuple(info.u) + tuple(info.outputs)
        shapes, frames, source = _generate(vis, state_names, system.param_names)
        view = None if vis.view is None else [float(c) for c in vis.view]
        return {"shapes": shapes, "frames": frames, "source": source, "view": view}

    key = built(system).key(system.default_variant)
    data = declared_data(key, system.visuals, "visuals", __file__, GENERATOR_VERSION, build)
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
