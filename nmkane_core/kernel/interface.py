"""The Python side of the compiled loops' interface: their arguments, status codes and stats.

The loops (``integrate_fixed``, ``integrate_adaptive`` in :mod:`nmkane_core.kernel.source.loops`,
pasted into every generated kernel by :mod:`nmkane_core.kernel.codegen`) take positional arguments
— the fastest call into numba.  Their argument lists are defined here once, as
:class:`FixedArgs` and :class:`AdaptiveArgs`, each field with the numba type of an
ordinary run next to it: the drivers call ``mod.integrate_fixed(*FixedArgs(...))`` and the
background precompile compiles :func:`fixed_loop_signature`.  The fields must be the
loops' parameters in order; this module checks that against the loops' source on import.

The status codes (``STATUS_*``), the layout of the ``stats`` array (``STATS_*``) and the
adaptive step-control constants (``STEP_*``) are plain literals at the top of
``_kernel_loops.py`` (the compiled code needs them as globals); they are read from that
source here, so that both sides share one definition.
"""

from __future__ import annotations

import ast
import typing
from pathlib import Path
from typing import Annotated, Any, NamedTuple

import numpy as np

__all__ = [
    "FixedArgs",
    "AdaptiveArgs",
    "fixed_loop_signature",
    "loop_signature",
    "STATUS_OK",
    "STATUS_J2_SINGULAR",
    "STATUS_T_SINGULAR",
    "STATUS_DIVERGED",
    "STATUS_FAILED",
    "STATUS_BUDGET",
    "STATUS_PROJECTION_FAILED",
    "STATS_E0",
    "STATS_MAX_DRIFT",
    "STATS_FINAL_DRIFT",
    "STATS_RCOND_J2",
    "STATS_RCOND_T",
    "STATS_VIOL",
]

_SOURCE = Path(__file__).parent / "source" / "loops.py"
_TREE = ast.parse(_SOURCE.read_text())


def _literals(tree: ast.Module) -> dict[str, int | float]:
    out = {}
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and len(node.targets) == 1
            and isinstance(node.targets[0], ast.Name)
            and node.targets[0].id.startswith(("STATUS_", "STATS_", "STEP_"))
        ):
            out[node.targets[0].id] = ast.literal_eval(node.value)
    return out


_C = _literals(_TREE)

STATUS_OK: int = int(_C["STATUS_OK"])
STATUS_J2_SINGULAR: int = int(_C["STATUS_J2_SINGULAR"])
STATUS_T_SINGULAR: int = int(_C["STATUS_T_SINGULAR"])
STATUS_DIVERGED: int = int(_C["STATUS_DIVERGED"])
STATUS_FAILED: int = int(_C["STATUS_FAILED"])
STATUS_BUDGET: int = int(_C["STATUS_BUDGET"])
STATUS_PROJECTION_FAILED: int = int(_C["STATUS_PROJECTION_FAILED"])
STATS_E0: int = int(_C["STATS_E0"])
STATS_MAX_DRIFT: int = int(_C["STATS_MAX_DRIFT"])
STATS_FINAL_DRIFT: int = int(_C["STATS_FINAL_DRIFT"])
STATS_RCOND_J2: int = int(_C["STATS_RCOND_J2"])
STATS_RCOND_T: int = int(_C["STATS_RCOND_T"])
STATS_VIOL: int = int(_C["STATS_VIOL"])

# numba types of the fields, by name (numba is imported only when a signature is asked for)
VEC = "float64[::1]"
MAT = "float64[:, ::1]"
FLOAT = "float64"
INT = "int64"
PROJ = "proj"  # int64[::1] with a projection, None without (see ProjectionOptions)


class FixedArgs(NamedTuple):
    """``integrate_fixed``'s arguments, in order: steps k0 … k1−1 of a run of ``nsteps`` steps."""

    x: Annotated[np.ndarray, VEC]  # state, advanced in place
    t0: Annotated[float, FLOAT]
    dt: Annotated[float, FLOAT]
    t_final: Annotated[float, FLOAT]
    k0: Annotated[int, INT]
    k1: Annotated[int, INT]
    nsteps: Annotated[int, INT]
    every: Annotated[int, INT]  # keep every ``every``-th state
    p: Annotated[np.ndarray, VEC]  # parameters
    G: Annotated[np.ndarray, MAT]  # Γ
    G1: Annotated[np.ndarray, MAT]  # Γ1
    G2: Annotated[np.ndarray, MAT]  # Γ2
    TA: Annotated[np.ndarray, MAT]  # tableau A, b, c
    TB: Annotated[np.ndarray, VEC]
    TC: Annotated[np.ndarray, VEC]
    rcond_min: Annotated[float, FLOAT]  # stop threshold of the rcond estimates
    proj: Annotated[np.ndarray | None, PROJ]
    out_t: Annotated[np.ndarray, VEC]  # output rows
    out_x: Annotated[np.ndarray, MAT]
    out_E: Annotated[np.ndarray, VEC]
    out_V: Annotated[np.ndarray, MAT]
    row: Annotated[int, INT]  # next free output row
    stats: Annotated[np.ndarray, VEC]  # running statistics (STATS_*), updated in place


class AdaptiveArgs(NamedTuple):
    """``integrate_adaptive``'s arguments, in order: from t until t_final, a full output
    buffer, or ``max_steps`` attempts."""

    x: Annotated[np.ndarray, VEC]  # state, advanced in place
    t: Annotated[float, FLOAT]
    t_final: Annotated[float, FLOAT]
    h: Annotated[float, FLOAT]  # first step to try
    rtol: Annotated[float, FLOAT]
    atol: Annotated[float, FLOAT]
    hmin: Annotated[float, FLOAT]
    hmax: Annotated[float, FLOAT]
    max_steps: Annotated[int, INT]  # attempts allowed in this call
    every: Annotated[int, INT]
    accepted: Annotated[int, INT]  # accepted steps so far (for ``every``)
    p: Annotated[np.ndarray, VEC]
    G: Annotated[np.ndarray, MAT]
    G1: Annotated[np.ndarray, MAT]
    G2: Annotated[np.ndarray, MAT]
    TA: Annotated[np.ndarray, MAT]  # tableau A, b, E = b − b̂, c
    TB: Annotated[np.ndarray, VEC]
    TE: Annotated[np.ndarray, VEC]
    TC: Annotated[np.ndarray, VEC]
    err_exp: Annotated[float, FLOAT]  # step-control exponent 1/(q+1)
    rcond_min: Annotated[float, FLOAT]
    proj: Annotated[np.ndarray | None, PROJ]
    out_t: Annotated[np.ndarray, VEC]  # output buffer (its length caps the rows of a call)
    out_x: Annotated[np.ndarray, MAT]
    out_E: Annotated[np.ndarray, VEC]
    out_V: Annotated[np.ndarray, MAT]
    stats: Annotated[np.ndarray, VEC]


LOOPS: dict[str, Any] = {"integrate_fixed": FixedArgs, "integrate_adaptive": AdaptiveArgs}


def loop_signature(args: type[NamedTuple], projected: bool = False) -> tuple:
    """numba types of a loop's arguments (``proj`` an int64 array when ``projected``, else None)."""
    from numba import types

    names = {
        VEC: types.float64[::1],
        MAT: types.float64[:, ::1],
        FLOAT: types.float64,
        INT: types.int64,
        PROJ: types.int64[::1] if projected else types.none,
    }
    hints = typing.get_type_hints(args, include_extras=True)
    return tuple(names[hints[f].__metadata__[0]] for f in args._fields)


def fixed_loop_signature() -> tuple:
    """The signature every unprojected fixed-step run calls ``integrate_fixed`` with."""
    return loop_signature(FixedArgs)


def _check(tree: ast.Module) -> None:
    defs = {n.name: [a.arg for a in n.args.args] for n in tree.body if isinstance(n, ast.FunctionDef)}
    for name, args in LOOPS.items():
        if defs.get(name) != list(args._fields):
            raise RuntimeError(
                f"nmkane_core.kernel.interface.{args.__name__} lists {args._fields}, but "
                f"_kernel_loops.{name} takes {defs.get(name)}"
            )


_check(_TREE)
del _TREE
