"""A system's declared visuals (:mod:`nmkane_core.declare.visuals`) compiled into numpy pose functions.

:func:`compile_visuals` turns the declaration into :class:`CompiledVisuals`: the shape
table (one :class:`CompiledShape` per shape: its kind, plain fields and a :class:`Slot`
per expression field, JSON-able) and generated numpy source with two functions, ``sizes(p)`` and
``poses(s, p)`` (``s``: state name → array over rows, so a whole trajectory is evaluated
at once).  The source is cached on disk under ``<cache root>/visuals/`` keyed by the
system's kernel key (:meth:`nmkane_core.kernel.built.Built.key`) and the file defining the visuals,
so a later process loads it without sympy.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..declare.visuals import AXES, SHAPES, Shape, Visuals
from ..errors import InputError
from .built import built
from .cache import declared_data

__all__ = ["AXES", "CompiledShape", "CompiledVisuals", "Slot", "axis_wxyz", "compile_visuals", "rotation_to_wxyz"]

GENERATOR_VERSION = "3"  # 3: shapes as CompiledShape records (kind, plain fields, slots per field)


@dataclass(frozen=True)
class Slot:
    """Where one field's numbers sit in the outputs of ``sizes`` (parameter fields) or
    ``poses`` (state fields): from ``start``, ``shape`` of them (() a number, (3,) a point,
    (m, 3) points)."""

    start: int
    shape: tuple[int, ...]

    @property
    def count(self) -> int:
        return math.prod(self.shape)

    def take(self, sizes: np.ndarray) -> Any:
        """The field's value from the ``sizes`` vector: a float, or an array of ``shape``."""
        v = np.asarray(sizes[self.start : self.start + self.count], float)
        return float(v[0]) if self.shape == () else v.reshape(self.shape)

    def rows(self, out: list[np.ndarray]) -> np.ndarray:
        """The field over the rows of a run from the ``poses`` outputs: (n, *shape)."""
        n = len(out[self.start]) if self.count else 0
        return np.stack(out[self.start : self.start + self.count], axis=1).reshape(n, *self.shape)


@dataclass(frozen=True)
class CompiledShape:
    """One declared shape, compiled: its kind (a key of :data:`~nmkane_core.declare.visuals.SHAPES`),
    name, frame, its plain fields (colours, an axis, a text) and a :class:`Slot` per
    expression field (None: the optional field was not given)."""

    kind: str
    name: str
    frame: str | None
    plain: dict[str, Any]
    params: dict[str, Slot | None]
    state: dict[str, Slot | None]

    @property
    def type(self) -> type[Shape]:
        return SHAPES[self.kind]

    @property
    def fixed(self) -> bool:
        """On the world and not moving with the state (the ground, a surface, an anchor)."""
        return self.frame is None and not any(self.state.values())

    def resolve(self, sizes: np.ndarray) -> Shape:
        """The declared kind's class with its parameter fields as numbers (for these sizes)
        and its state fields as their :class:`Slot` (None where not given)."""
        values = {k: None if v is None else v.take(sizes) for k, v in self.params.items()}
        make: Callable[..., Shape] = self.type  # the kind's class, called with its own fields
        return make(name=self.name, frame=self.frame, **self.plain, **values, **self.state)

    def to_json(self) -> dict:
        def slots(d):
            return {k: None if v is None else [v.start, list(v.shape)] for k, v in d.items()}

        return {
            "kind": self.kind,
            "name": self.name,
            "frame": self.frame,
            "plain": self.plain,
            "params": slots(self.params),
            "state": slots(self.state),
        }

    @classmethod
    def from_json(cls, d: dict) -> CompiledShape:
        def slots(m):
            return {k: None if v is None else Slot(int(v[0]), tuple(v[1])) for k, v in m.items()}

        plain = {k: tuple(v) if isinstance(v, list) else v for k, v in d["plain"].items()}
        return cls(d["kind"], d["name"], d["frame"], plain, slots(d["params"]), slots(d["state"]))


@dataclass
class CompiledVisuals:
    """Numeric pose functions of a system's visuals (no sympy).

    ``shapes``: one :class:`CompiledShape` per declared shape (its slots index the outputs
    of ``sizes`` and ``poses``); ``frames``: frame name → index of its 12 pose outputs
    (origin, then the rotation row by row)."""

    shapes: list[CompiledShape]
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


def _flat(value) -> tuple[list, tuple[int, ...]]:
    """A field's expressions in order, and its shape: () one, (3,) a point, (m, 3) points."""
    if not isinstance(value, (tuple, list)):
        return [value], ()
    parts = [_flat(v) for v in value]
    inner = {shape for _, shape in parts}
    if len(inner) > 1:
        raise ValueError(f"ragged field: {value!r}")
    return [e for exprs, _ in parts for e in exprs], (len(parts), *(inner.pop() if inner else ()))


class _Outputs:
    """The expressions of one generated function (``sizes`` or ``poses``), each checked to
    use only the ``allowed`` names (``what`` says which, in the refusal)."""

    def __init__(self, names: set[str], allowed: set[str], what: str):
        self.names, self.allowed, self.what = names, allowed, what
        self.exprs: list = []

    def add(self, exprs, where: str) -> int:
        start = len(self.exprs)
        for e in exprs:
            e = _plain(e, self.names)
            bad = sorted(s.name for s in e.free_symbols if s.name not in self.allowed)
            if bad:
                raise InputError(where, bad[0], f"names of {self.what}", "unknown name")
            self.exprs.append(e)
        return start

    def slot(self, value, where: str) -> Slot | None:
        if value is None:
            return None
        exprs, shape = _flat(value)
        return Slot(self.add(exprs, where), shape)


def _compile_shape(s: Shape, sizes: _Outputs, poses: _Outputs) -> CompiledShape:
    where = f"visuals.{s.name}"
    plain = {k: getattr(s, k) for k in s.plain_fields()}
    plain = {k: list(v) if isinstance(v, tuple) else v for k, v in plain.items()}  # as JSON has them
    params = {k: sizes.slot(getattr(s, k), f"{where}.{k}") for k in s.PARAM_FIELDS}
    state = {k: poses.slot(getattr(s, k), f"{where}.{k}") for k in s.STATE_FIELDS}
    return CompiledShape(s.kind, s.name, s.frame, plain, params, state)


def _source(size_exprs: list, pose_exprs: list, state_names: Sequence[str]) -> str:
    """The numpy source of ``sizes(p)`` and ``poses(s, p)`` (common subexpressions named once)."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    printer = NumPyPrinter({"fully_qualified_modules": True})

    def function(exprs, fn: str) -> list[str]:
        used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        lines = [f"def {fn}({'s, p' if fn == 'poses' else 'p'}):"]
        for name in sorted(s.name for s in used):
            src = "s" if fn == "poses" and name in state_names else "p"
            lines.append(f"    {_ident(name)} = {src}[{name!r}]")
        exprs = [e.subs({s: sp.Symbol(_ident(s.name), real=True) for s in e.free_symbols}) for e in exprs]
        subs, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_c"))
        lines += [f"    {sym} = {printer.doprint(e)}" for sym, e in subs]
        lines.append("    return [" + ", ".join(printer.doprint(e) for e in reduced) + "]")
        return lines

    src = ["import functools", "import numpy", "", ""]
    src += [*function(size_exprs, "sizes"), "", ""]
    src += [*function(pose_exprs, "poses"), ""]
    return "\n".join(src)


def _generate(
    vis: Visuals, state_names: Sequence[str], param_names: Sequence[str]
) -> tuple[list[CompiledShape], dict, str]:
    """The shape table, frame index and numpy source of a declaration (sympy)."""
    import sympy as sp

    names = set(state_names) | set(param_names)
    sizes = _Outputs(names, set(param_names), "parameters")
    poses = _Outputs(names, names, "coordinates, speeds and parameters")
    frames: dict = {}
    for f in vis.frames:
        rot = sp.eye(3) if f.rotation is None else sp.Matrix(f.rotation)
        if rot.shape != (3, 3) or len(tuple(f.origin)) != 3:
            raise InputError(f"visuals.{f.name}", f.name, "origin of 3 expressions and a 3×3 rotation", "bad shape")
        frames[f.name] = poses.add(list(f.origin) + list(rot), f"visuals.{f.name}")
    shapes = [_compile_shape(s, sizes, poses) for s in vis.shapes]
    return shapes, frames, _source(sizes.exprs, poses.exprs, state_names)


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
        return {"shapes": [c.to_json() for c in shapes], "frames": frames, "source": source, "view": view}

    key = built(system).key(system.default_variant)
    data = declared_data(key, system.visuals, "visuals", __file__, GENERATOR_VERSION, build)
    view = data.get("view")
    shapes = [CompiledShape.from_json(d) for d in data["shapes"]]
    compiled = CompiledVisuals(shapes, data["frames"], data["source"], None if view is None else tuple(view))
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
