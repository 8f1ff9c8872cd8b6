"""Plotted quantities typed as expressions — ``theta``, ``u1*cos(theta)``, ``dE/E0``,
``sqrt(u1^2 + u2^2)`` — read safely.

The text is parsed by Python's own parser (:func:`ast.parse`, ``mode="eval"``) and every
node is checked against a whitelist — numbers, the names of the run's quantities, the
arithmetic operators and a few functions — before anything is computed; the expression is
then evaluated by walking that tree with numpy (:func:`evaluate`).  Nothing typed is ever
handed to ``eval``/``exec`` (sympy's ``parse_expr`` would: it evaluates the text it
transforms), so a name, an attribute, a call or a string that is not on the list is refused
with the reason.

The names a run offers (:func:`quantities`): ``t``; the state (coordinates, speeds and the
model's outputs); ``E`` (energy) and ``dE`` (its drift E − E(0)); each constraint's violation
as ``phi_<name>``; and, when runs carry them, the generalized constraint forces
``F_<speed>``, the multipliers ``lambda_<constraint>`` and the components of the forces
the system declares at points, ``R_<force>_<label>`` (the run's ``contact.normal`` is
``R_contact_normal``).

The page's plot boxes and ``nmkane run --plot`` read expressions through this one module.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping

import numpy as np

FUNCTIONS: dict[str, Callable] = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "atan2": np.arctan2,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "tanh": np.tanh,
    "exp": np.exp,
    "log": np.log,
    "log10": np.log10,
    "sqrt": np.sqrt,
    "abs": np.abs,
    "sign": np.sign,
    "hypot": np.hypot,
    "min": np.minimum,
    "max": np.maximum,
}
CONSTANTS = {"pi": math.pi, "e": math.e}
_BINARY: dict[type, Callable] = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
    ast.Mod: operator.mod,
}
_UNARY: dict[type, Callable] = {ast.UAdd: operator.pos, ast.USub: operator.neg}
MAX_LENGTH = 200  # characters
MAX_NODES = 200


class ExpressionError(ValueError):
    """An expression that cannot be read, with the reason (shown beside its box)."""


def parse(text: str, names) -> ast.Expression:
    """The checked syntax tree of ``text`` (``^`` is read as a power), or ExpressionError."""
    if not isinstance(text, str) or not text.strip():
        raise ExpressionError("the box is empty: type a quantity, e.g. theta or u1*cos(theta)")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"longer than {MAX_LENGTH} characters")
    src = text.strip().replace("^", "**").replace("\u2212", "-")
    try:
        tree = ast.parse(src, mode="eval")
    except SyntaxError:
        raise ExpressionError(f"{text!r} is not an expression (e.g. u1*cos(theta), x^2 + y^2)") from None
    allowed = set(names)
    nodes = list(ast.walk(tree))
    if len(nodes) > MAX_NODES:
        raise ExpressionError("too long an expression")
    for node in nodes:
        _check(node, allowed)
    return tree


def _check(node: ast.AST, allowed: set[str]) -> None:
    if isinstance(node, (ast.Expression, ast.Load, *_BINARY, *_UNARY)):
        return
    if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
        return
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
        return
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not isinstance(node.value, bool):
        return
    if isinstance(node, ast.Name):
        if node.id in allowed or node.id in CONSTANTS or node.id in FUNCTIONS:
            return
        raise ExpressionError(f"unknown name {node.id!r} (known: {', '.join(sorted(allowed))})")
    if isinstance(node, ast.Call):
        if isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS and not node.keywords:
            return
        raise ExpressionError(f"only these functions: {', '.join(FUNCTIONS)}")
    raise ExpressionError(f"{type(node).__name__.lower()} is not allowed in a plotted quantity")


def evaluate(tree: ast.Expression, values: Mapping[str, np.ndarray]) -> np.ndarray:
    """The checked expression over the rows of a run (``values``: name → array)."""

    def ev(node: ast.AST):
        if isinstance(node, ast.Expression):
            return ev(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):  # (parse allows no other)
            return np.float64(node.value)  # numpy arithmetic: 1/0 is inf, not an exception
        if isinstance(node, ast.Name):
            if node.id in values:
                return values[node.id]
            if node.id in CONSTANTS:
                return CONSTANTS[node.id]
            raise ExpressionError(f"{node.id!r} is a function: call it, e.g. {node.id}(theta)")
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](ev(node.left), ev(node.right))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](ev(node.operand))
        if isinstance(node, ast.Call):
            assert isinstance(node.func, ast.Name)  # checked by parse
            return FUNCTIONS[node.func.id](*(ev(a) for a in node.args))
        raise ExpressionError(f"{type(node).__name__} cannot be computed")  # pragma: no cover - parse refuses it

    with np.errstate(all="ignore"):
        try:
            out = ev(tree)
        except TypeError as e:  # a function given the wrong number of arguments
            raise ExpressionError(str(e)) from None
    n = len(next(iter(values.values()))) if values else 1
    return np.broadcast_to(np.asarray(out, float), (n,)).copy()


def quantities(run) -> dict[str, np.ndarray]:
    """The names a run offers to plotted expressions (see the module docstring)."""
    out: dict[str, np.ndarray] = {"t": np.asarray(run.t, float)}
    out.update({k: np.asarray(v, float) for k, v in run.state.items()})
    if run.energy is not None and len(run.energy):
        e = np.asarray(run.energy, float)
        out["E"], out["dE"] = e, e - e[0]
    out.update({f"phi_{k}": np.asarray(v, float) for k, v in run.violation.items()})
    for attr, prefix in (("constraint_forces", "F_"), ("multipliers", "lambda_")):
        out.update({f"{prefix}{k}": np.asarray(v, float) for k, v in (getattr(run, attr, None) or {}).items()})
    points = getattr(run, "point_forces", None) or {}
    out.update({"R_" + k.replace(".", "_"): np.asarray(v, float) for k, v in points.items()})
    return out


def names_of(state_names, constraint_names, has_energy: bool = True) -> tuple[str, ...]:
    """The names a system's runs offer (before a run exists: the page checks typed text)."""
    energy = ("E", "dE") if has_energy else ()
    return ("t", *state_names, *energy, *(f"phi_{c}" for c in constraint_names))
