"""A new kernel's first tier: its generated module run by Python while numba compiles it.

The first run after install waits for numba: a new kernel's stage and integrator loops take
seconds to compile (4–5 s for the paper's mechanism on 2 cores) for a run that then takes
milliseconds.  Yet the generated module is plain Python (numba's subset of it): imported again
with ``njit`` as a plain-Python wrapper (:func:`interpreted`), the same statements run at once in the
interpreter, about a thousand times slower than compiled — 0.03–0.1 s for the paper's
mechanism over 1 s at Δt = 0.01 (500 evaluations of the right-hand side).  Results agree with
the compiled code's to rounding (the compiled code fuses no multiply and add, ``codegen.FASTMATH``;
the math functions here are numpy's, the compiled code's the C library's).
The kernels are compiled with ``error_model="numpy"``: a square root of a negative number or a
division by zero gives NaN or ±inf, which the loops turn into a status.  The interpreted copy
keeps that: its ``math`` functions are numpy's (NaN, float64 results) and numpy's warnings are
silent, so a run that leaves its model's domain ends as the compiled one does.

Two uses, both while this process's new kernel is uncompiled
(:func:`~nmkane_core.kernel.precompile.uncompiled`):

* :func:`at_once` — a few evaluations at one state (completing or checking an initial state,
  picking a partition): interpreted, instead of compiling each function first;
* a short run (the run layer decides: :mod:`nmkane_core.run.plan`, from
  :func:`seconds_per_evaluation`) while the background child compiles the loop for the runs
  after it.

A kernel whose model functions are C (:mod:`~nmkane_core.kernel.native`, large models) is
never interpreted: numba calls that C, Python cannot.  ``NMKANE_INTERPRET=0`` turns the tier
off (every call compiled first, as before it).
"""

from __future__ import annotations

import contextlib
import contextvars
import functools
import math
import os
import threading
import time
import types
from pathlib import Path

import numpy as np

from . import precompile

__all__ = [
    "at_once",
    "compiled_only",
    "interpretable",
    "interpreted",
    "is_interpreted",
    "njit",
    "seconds_per_evaluation",
]

_IMPORT = "from numba import njit\n"
_SUFFIX = "_interpreted"
_MODULES: dict[str, types.ModuleType] = {}
_LOCK = threading.Lock()
_OFF = contextvars.ContextVar("nmkane_compiled_only", default=False)


@contextlib.contextmanager
def compiled_only():
    """Within it (this thread), nothing is interpreted: every call compiles or loads first —
    what a warm-up, which exists to compile, needs."""
    token = _OFF.set(True)
    try:
        yield
    finally:
        _OFF.reset(token)


_INSIDE = threading.local()


def _numpy_errors(func):
    """``func`` run with numpy's floating-point errors silent, as compiled code runs (the
    outermost call sets it; calls within run as they are)."""

    @functools.wraps(func)
    def run(*args, **kwargs):
        if getattr(_INSIDE, "on", False):
            return func(*args, **kwargs)
        _INSIDE.on = True
        try:
            with np.errstate(all="ignore"):
                return func(*args, **kwargs)
        finally:
            _INSIDE.on = False

    return run


def njit(*args, **kwargs):
    """numba's decorator for the interpreter: the function as written, its floating-point
    errors silent (``@njit`` and ``@njit(...)``)."""
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return _numpy_errors(args[0])
    return _numpy_errors


def _numpy_semantics(name: str):
    """``math.NAME`` as numba compiles it with ``error_model="numpy"``: NaN or ±inf where
    Python raises (the square root or logarithm of a negative number, an overflow), returned
    as numpy's float64, so that a division by it gives ±inf too.  The loops' finiteness checks
    then report it as compiled runs do (``diverged``)."""
    ufunc = getattr(np, _UFUNC.get(name, name))
    return lambda *xs: ufunc(*(np.float64(x) for x in xs))


#: math's functions whose numpy ufunc has another name
_UFUNC = {
    "asin": "arcsin",
    "acos": "arccos",
    "atan": "arctan",
    "atan2": "arctan2",
    "asinh": "arcsinh",
    "acosh": "arccosh",
    "atanh": "arctanh",
    "pow": "power",
    "fabs": "absolute",
}
_MATH_FLOAT = (
    "sqrt",
    "exp",
    "expm1",
    "log",
    "log2",
    "log10",
    "log1p",
    "sin",
    "cos",
    "tan",
    "asin",
    "acos",
    "atan",
    "atan2",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "pow",
    "fabs",
    "hypot",
    "copysign",
    "fmod",
)
#: the ``math`` the interpreted kernels see: Python's, with its floating functions given numba's semantics
numpy_math = types.SimpleNamespace(
    **{
        name: _numpy_semantics(name) if name in _MATH_FLOAT else getattr(math, name)
        for name in dir(math)
        if not name.startswith("_")
    }
)


def _source(path: str | None) -> str | None:
    if path is None:
        return None
    try:
        return Path(path).read_text()
    except OSError:
        return None


def interpretable(module) -> bool:
    """``module`` is a generated kernel Python can run (its model functions are not C), and
    the tier is on."""
    if is_interpreted(module):
        return True
    if _OFF.get() or os.environ.get("NMKANE_INTERPRET", "1") == "0":
        return False
    return _python_only(module.__name__, getattr(module, "__file__", None))


@functools.cache
def _python_only(name: str, path: str | None) -> bool:
    """The kernel's text has no C functions (read once per kernel)."""
    source = _source(path)
    return source is not None and _IMPORT in source and "ExternalFunction" not in source


def is_interpreted(module) -> bool:
    return module.__name__.endswith(_SUFFIX)


def interpreted(module) -> types.ModuleType:
    """The kernel ``module`` imported again with ``njit`` as a plain-Python wrapper (made once per kernel)."""
    if is_interpreted(module):
        return module
    with _LOCK:
        found = _MODULES.get(module.__name__)
        if found is None:
            source = _source(getattr(module, "__file__", None))
            if source is None or not interpretable(module):
                raise ValueError(f"kernel {module.__name__} cannot be interpreted (C model functions)")
            found = types.ModuleType(module.__name__ + _SUFFIX)
            found.__file__ = module.__file__
            text = source.replace(_IMPORT, f"from {__name__} import njit\n")
            text = text.replace("import math\n", f"from {__name__} import numpy_math as math\n")
            code = compile(text, module.__file__, "exec")
            exec(code, found.__dict__)  # the generated kernel's own text, as imported
            _MODULES[module.__name__] = found
        return found


def at_once(module):
    """The module to call for a few evaluations now: the interpreted copy while ``module`` is
    a kernel this process wrote and has not compiled yet, else ``module`` itself."""
    if is_interpreted(module) or not precompile.uncompiled(module) or not interpretable(module):
        return module  # (the cheap test first: this is asked before every run)
    return interpreted(module)


def seconds_per_evaluation(module, x: np.ndarray, p: np.ndarray, G, G1, G2, calls: int = 3) -> float:
    """The interpreter's time for one right-hand side of ``module`` at state ``x`` (the best of
    ``calls``)."""
    py = interpreted(module)
    K, w = np.empty((1, x.size)), py.make_workspace()
    best = float("inf")
    for _ in range(calls):
        t0 = time.perf_counter()
        py.rhs_ws(0.0, x, p, G, G1, G2, K, 0, w)
        best = min(best, time.perf_counter() - t0)
    return best
