"""A model's compiled kernel: its description, its C functions, and the compiled core that runs it.

:class:`CModel` is what :class:`~nmkane_core.kernel.interface.CompiledModel` names: the sizes
of the model and the loops and evaluations the integrators call.  It holds

* the model's description (:func:`~nmkane_core.kernel.codegen.generate_source`: sizes, the work
  arrays' offsets, the permutation and sparsity, and the C text of its straight-line
  functions), read from the kernel cache;
* the model's library, those functions compiled by the machine's C compiler into the cache
  (:mod:`nmkane_core.kernel.native`);
* the record :mod:`nmkane_core.kernel.core` passes to the compiled core with every call: the
  sizes and offsets, and pointers to the model's arrays and functions.

Arrays go to C as pointers, so they must be C-contiguous float64 (int64 for the partition and
the projection's options); :func:`_ptr` says which argument is not.
"""

from __future__ import annotations

import ctypes
import json
import threading
from collections.abc import Callable
from typing import Any

import numpy as np

from . import constants, core, special
from .interface import AdaptiveArgs, FixedArgs

__all__ = ["CModel", "SV"]

#: the robust solve's settings and state at w[OSV + SV_*] (csrc/nmk.h)
SV = {
    "SV_MODE": 0,
    "SV_RANK_TOL": 1,
    "SV_MAX_RANK": 2,
    "SV_CONSISTENCY_TOL": 3,
    "SV_RCOND_ROBUST": 4,
    "SV_RCOND_MIN": 5,
    "SV_USED": 6,
    "SV_CHANGED": 7,
    "SV_STATUS": 8,
    "SV_RANK": 9,
    "SV_RESIDUAL": 10,
    "SV_PIVOT": 11,
    "SV_ESTIMATE": 12,
    "SV_FORCES": 13,
    "SV_LEAVE": 14,
    "SV_STAB": 15,
    "SV_FADE": 16,
    "SV_NEAR": 17,
}


def _ptr(a: np.ndarray, name: str, dtype=np.float64) -> int:
    """The address of a C-contiguous array of ``dtype`` (what the core reads and writes)."""
    if not isinstance(a, np.ndarray) or a.dtype != dtype or not a.flags.c_contiguous:
        what = (
            type(a).__name__ if not isinstance(a, np.ndarray) else f"{a.dtype} array, contiguous={a.flags.c_contiguous}"
        )
        raise TypeError(f"{name}: a C-contiguous {np.dtype(dtype)} array is needed, got {what}")
    if not a.flags.writeable and name in _WRITTEN:
        raise TypeError(f"{name}: the array is written by the kernel, and this one is read-only")
    return a.ctypes.data


_SPECIAL_LOCK = threading.Lock()
#: the arguments the core writes into
_WRITTEN = frozenset(
    [
        "x",
        "K",
        "w",
        "E",
        "V",
        "O",
        "F",
        "L",
        "stats",
        "order",
        "solve_log",
        "out_t",
        "out_x",
        "out_E",
        "out_V",
        "out_F",
        "out_L",
    ]
)


class CModel:
    """A model's kernel: its sizes as attributes (``N``, ``M``, ``PI``, ``NV``, ``NO``, ``PERM``,
    ``ROBUST``, the work-array offsets ``OJ`` …), and the compiled core's entry points bound to it."""

    # the sizes and offsets named in this module (every other field of the record is set too)
    N: int
    M: int
    MNH: int
    MH: int
    PI: int
    NV: int
    NO: int
    WSIZE: int
    ORC: int
    OSV: int
    MAX_RANK_DEFAULT: int
    ROBUST: bool
    DECLARED: bool
    KN: int
    OQ: int
    PERM: np.ndarray

    def __init__(self, name: str, description: dict[str, Any], library: ctypes.CDLL, path: str = ""):
        self.__name__ = name
        self.__file__ = path
        self.description = description
        self._lib = library  # kept alive: the record points into it
        self._generic = core.library()
        self._core = self._generic  # the specialised build once it is there (specialize)
        self._special: threading.Thread | None = None
        rec = core.ModelRecord()  # the record's fields, also the kernel's attributes
        for key in (*core.MODEL_INTS, *core.offset_names()):
            value = int(description["ints"][key])
            setattr(self, key, value)
            setattr(rec, key, value)
        for key in core.MODEL_FLOATS:
            setattr(self, key, float(description["floats"][key]))
            setattr(rec, key, getattr(self, key))
        self._arrays = {}  # kept alive: the record points into them
        for key in core.MODEL_ARRAYS:
            arr = np.ascontiguousarray(description["arrays"][key] or [0], dtype=np.int64)
            self._arrays[key] = arr
            setattr(rec, key, arr.ctypes.data)
        self.PERM = self._arrays["PERM"][: self.N].copy()
        tag = description["tag"]
        for fname, _ in core.MODEL_FUNCTIONS:
            setattr(rec, fname, ctypes.cast(getattr(library, f"nmk_{tag}_{fname}"), ctypes.c_void_p).value)
        self.ROBUST, self.DECLARED = bool(self.ROBUST), bool(self.DECLARED)
        self._rec = rec
        self._md = ctypes.addressof(rec)
        for key, value in SV.items():
            setattr(self, key, value)
        for key in constants.NAMES:
            setattr(self, key, getattr(constants, key))
        if path and special.library_path(path).exists():  # built by an earlier process
            self._use_special(special.library_path(path))

    # ------------------------------------------------------------------ the specialised build
    @property
    def specialized(self) -> bool:
        """Whether the calls go to the model's specialised build (:mod:`~nmkane_core.kernel.special`)."""
        return self._core is not self._generic

    def specialize(self, wait: bool = False) -> None:
        """Start the specialised build in a background thread (once), unless it is there; calls
        switch to it when it is ready.  ``wait``: return when it is (or when it failed)."""
        if self.specialized or not self.__file__:
            return
        with _SPECIAL_LOCK:
            if self._special is None:
                self._special = threading.Thread(target=self._build_special, name="nmkane-specialize", daemon=True)
                self._special.start()
            thread = self._special
        if wait:
            thread.join()

    def _build_special(self) -> None:
        from .native import NativeBuildError, log

        path = special.library_path(self.__file__)
        try:
            if not path.exists():
                special.build(self.description, path)
            self._use_special(path)
        except (NativeBuildError, OSError) as e:  # the generic core goes on: slower, the same numbers
            log.warning("nmkane: the specialised build of %s failed (%s); the generic core runs it", self.__name__, e)

    def _use_special(self, path) -> None:
        try:
            lib = core.declare(ctypes.CDLL(str(path)))
        except (OSError, AttributeError):  # damaged: the generic core goes on, a next build replaces it
            return
        self._core = lib

    # ------------------------------------------------------------------ loops
    def _loop_record(self, record_type, fields, args):
        rec = record_type()
        hints = core.loop_kinds(fields)
        for name, value in zip(fields._fields, args, strict=True):
            kind = hints[name]
            if kind == "vec" or kind == "mat":
                setattr(rec, name, _ptr(value, name))
                setattr(rec, f"{name}_n0", value.shape[0])
                if kind == "mat":
                    setattr(rec, f"{name}_n1", value.shape[1])
            elif kind == "ivec":
                setattr(rec, name, _ptr(value, name, np.int64))
                setattr(rec, f"{name}_n0", value.shape[0])
            elif kind == "proj":
                if value is not None:
                    setattr(rec, name, _ptr(value, name, np.int64))
                    setattr(rec, f"{name}_n0", value.shape[0])
            else:
                setattr(rec, name, value)
        self._check_sizes(dict(zip(fields._fields, args, strict=True)))
        return rec

    def _check_sizes(self, a: dict) -> None:
        """The arrays the loops index by the model's sizes must be that large (C does not check)."""
        n2, S = 2 * self.N, a["TC"].shape[0]
        need = {
            "x": (n2,),
            "TA": (S, S),
            "TB": (S,),
            "order": (self.N + 1,),
            "stats": (constants.STATS_VIOL + self.NV,),
        }
        if "TE" in a:
            need["TE"] = (S,)
        for name, shape in need.items():
            if a[name].shape[: len(shape)] != shape and not (
                name in ("order", "stats") and a[name].shape[0] >= shape[0]
            ):
                raise ValueError(f"{name}: shape {a[name].shape}, the kernel needs {shape}")
        rows = a["out_t"].shape[0]
        for name, cols in (("out_x", n2), ("out_V", self.NV)):
            if a[name].shape[0] < rows or a[name].shape[1] != cols:
                raise ValueError(f"{name}: shape {a[name].shape}, the kernel needs ({rows}, {cols})")
        for name, cols in (("out_F", self.N), ("out_L", self.M)):
            if a[name].shape[0] and (a[name].shape[0] < rows or a[name].shape[1] != cols):
                raise ValueError(f"{name}: shape {a[name].shape}, the kernel needs ({rows}, {cols})")
        for name, size in (("G", self.MNH), ("G1", self.MH), ("G2", self.MH)):
            if a[name].shape != (size, size):
                raise ValueError(f"{name}: shape {a[name].shape}, the kernel needs ({size}, {size})")
        if a["p"].shape[0] < self.description["np"]:
            raise ValueError(f"p: {a['p'].shape[0]} values, the kernel needs {self.description['np']}")

    def integrate_fixed(self, *args) -> tuple[int, int, int, int]:
        """``FixedArgs`` → (status, steps done so far, next free row, pending row)."""
        rec = self._loop_record(core.FixedRecord, FixedArgs, args)
        ret = np.zeros(8)
        status = self._core.nmk_integrate_fixed(self._md, ctypes.addressof(rec), ret.ctypes.data)
        return int(status), int(ret[0]), int(ret[1]), int(ret[2])

    def integrate_adaptive(self, *args) -> tuple[int, float, float, int, int, int, int]:
        """``AdaptiveArgs`` → (status, t, h, rows written, accepted steps, attempted steps, pending row)."""
        rec = self._loop_record(core.AdaptiveRecord, AdaptiveArgs, args)
        ret = np.zeros(8)
        status = self._core.nmk_integrate_adaptive(self._md, ctypes.addressof(rec), ret.ctypes.data)
        return int(status), float(ret[0]), float(ret[1]), int(ret[2]), int(ret[3]), int(ret[4]), int(ret[5])

    # ------------------------------------------------------------------ evaluations at given states
    def make_workspace(self) -> np.ndarray:
        w = np.empty(self.WSIZE)
        self._core.nmk_make_workspace(self._md, w.ctypes.data)
        return w

    def _gammas(self, G, G1, G2) -> tuple[int, int, int]:
        for name, g, size in (("G", G, self.MNH), ("G1", G1, self.MH), ("G2", G2, self.MH)):
            if g.shape != (size, size):
                raise ValueError(f"{name}: shape {g.shape}, the kernel needs ({size}, {size})")
        return _ptr(G, "G"), _ptr(G1, "G1"), _ptr(G2, "G2")

    def _state(self, x: np.ndarray, name: str = "x") -> int:
        if x.shape != (2 * self.N,):
            raise ValueError(f"{name}: shape {x.shape}, the kernel needs ({2 * self.N},)")
        return _ptr(x, name)

    def _params(self, p: np.ndarray) -> int:
        if p.shape[0] < self.description["np"]:
            raise ValueError(f"p: {p.shape[0]} values, the kernel needs {self.description['np']}")
        return _ptr(p, "p")

    def rhs_ws(self, t, x, p, G, G1, G2, K, row, w) -> None:
        """ẋ into K[row] (w: a work array of :meth:`make_workspace`)."""
        if K.ndim != 2 or K.shape[1] != 2 * self.N or not 0 <= row < K.shape[0] or w.shape != (self.WSIZE,):
            raise ValueError(f"K {K.shape} row {row}, w {w.shape}: not this kernel's sizes")
        self._core.nmk_rhs_ws(
            self._md, float(t), self._state(x), self._params(p), *self._gammas(G, G1, G2), _ptr(K, "K"), int(row),
            _ptr(w, "w"),
        )  # fmt: skip

    def rhs_bound(self, p, G, G1, G2, K, w) -> Callable[[float, np.ndarray], None]:
        """``rhs_ws`` with everything but (t, x) fixed: ``f(t, x)`` puts ẋ into K[0].  The arrays
        are checked once and kept alive by ``f`` (a caller that evaluates many states, as scipy's
        solvers do, pays for a pointer and a call only)."""
        if K.ndim != 2 or K.shape[1] != 2 * self.N or w.shape != (self.WSIZE,):
            raise ValueError(f"K {K.shape}, w {w.shape}: not this kernel's sizes")
        fixed = (self._params(p), *self._gammas(G, G1, G2), _ptr(K, "K"), 0, _ptr(w, "w"))
        keep = (p, G, G1, G2, K, w)
        n2, md = 2 * self.N, self._md

        def f(t: float, x: np.ndarray) -> None:
            if x.dtype != np.float64 or x.shape != (n2,) or not x.flags.c_contiguous:
                x = self._checked_state(x)
            self._core.nmk_rhs_ws(md, t, x.ctypes.data, *fixed)

        f.keep = keep  # type: ignore[attr-defined]
        return f

    def _checked_state(self, x) -> np.ndarray:
        x = np.ascontiguousarray(x, dtype=np.float64)
        self._state(x)
        return x

    def rhs(self, t, x, p, G, G1, G2) -> tuple[np.ndarray, float, float]:
        """(ẋ, rcond J2, rcond T) at one state."""
        w = self.make_workspace()
        K = np.empty((1, 2 * self.N))
        self.rhs_ws(t, np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(p, dtype=float), G, G1, G2, K, 0, w)
        return K[0].copy(), float(w[self.ORC]), float(w[self.ORC + 1])

    def diagnostics(self, t, x, p, viol) -> float:
        if viol.shape[0] < self.NV:
            raise ValueError(f"viol: {viol.shape[0]} entries, the kernel needs {self.NV}")
        return self._core.nmk_diagnostics(self._md, float(t), self._state(x), self._params(p), _ptr(viol, "viol"))

    def _rows(self, ts, xs) -> tuple[int, int, int]:
        if xs.ndim != 2 or xs.shape[1] != 2 * self.N or ts.shape[0] != xs.shape[0]:
            raise ValueError(f"ts {ts.shape}, xs {xs.shape}: the kernel needs rows of {2 * self.N}")
        return ts.shape[0], _ptr(ts, "ts"), _ptr(xs, "xs")

    def diagnostics_rows(self, ts, xs, p, E, V) -> None:
        n, pt, px = self._rows(ts, xs)
        if E.shape[0] < n or V.shape[:1] < (n,) or (V.ndim != 2 or V.shape[1] != self.NV):
            raise ValueError(f"E {E.shape}, V {V.shape}: the kernel needs ({n},), ({n}, {self.NV})")
        self._core.nmk_diagnostics_rows(self._md, n, pt, px, self._params(p), _ptr(E, "E"), _ptr(V, "V"))

    def outputs_rows(self, ts, xs, p, O) -> None:
        n, pt, px = self._rows(ts, xs)
        if O.ndim != 2 or O.shape[0] < n or O.shape[1] != self.NO:
            raise ValueError(f"O {O.shape}: the kernel needs ({n}, {self.NO})")
        self._core.nmk_outputs_rows(self._md, n, pt, px, self._params(p), _ptr(O, "O"))

    def forces_rows(self, ts, xs, p, G, G1, G2, F, L) -> None:
        n, pt, px = self._rows(ts, xs)
        if F.shape != (n, self.N) or L.shape != (n, self.M):
            raise ValueError(f"F {F.shape}, L {L.shape}: the kernel needs ({n}, {self.N}), ({n}, {self.M})")
        self._core.nmk_forces_rows(
            self._md, n, pt, px, self._params(p), *self._gammas(G, G1, G2), _ptr(F, "F"), _ptr(L, "L")
        )

    def state_terms(self, t, x, p):
        """(J in the model's speed order, [φ; ψ̇], ψ, ∂ψ/∂q, reported violations) at one state."""
        J = np.empty((self.M, self.N))
        c = np.empty(self.M)
        psi = np.empty(self.MH)
        psi_q = np.empty((self.MH, self.N))
        viol = np.empty(self.NV)
        self._core.nmk_state_terms(
            self._md, float(t), self._state(x), self._params(p), *(a.ctypes.data for a in (J, c, psi, psi_q, viol))
        )
        return J, c, psi, psi_q, viol

    def _project(self, t, x, p, proj, max_rank: int) -> tuple[np.ndarray, int]:
        y = np.array(x, dtype=float)
        if proj is None or proj.shape[0] < 8:
            raise ValueError("proj: the projection's 8 options are needed")
        code = self._core.nmk_project_state(
            self._md, float(t), self._state(y), self._params(p), _ptr(proj, "proj", np.int64), int(max_rank)
        )
        if code < 0:
            raise MemoryError("the projection's work arrays could not be allocated")
        return y, int(code)

    def project_state(self, t, x, p, proj) -> tuple[np.ndarray, int]:
        """One state projected onto the constraint manifold (initial states): (x, code)."""
        return self._project(t, x, p, proj, -1)

    def project_state_robust(self, t, x, p, proj, max_rank) -> tuple[np.ndarray, int]:
        """``project_state`` with the rank of the model's constraints (kernels with ROBUST)."""
        return self._project(t, x, p, proj, max_rank)

    def solve_setup(self, w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, projected):
        if order.shape[0] < self.N + 1:
            raise ValueError(f"order: {order.shape[0]} entries, the kernel needs {self.N + 1}")
        self._core.nmk_solve_setup(
            self._md, _ptr(w, "w"), int(solve), float(rank_tol), int(max_rank), float(consistency_tol),
            float(rcond_robust), float(rcond_min), _ptr(order, "order", np.int64), int(bool(projected)),
        )  # fmt: skip

    def _robust_outcome(self, t, h, w, stats, order, solve_log, start) -> int:
        return int(
            self._core.nmk_robust_outcome(
                self._md,
                float(t),
                float(h),
                _ptr(w, "w"),
                _ptr(stats, "stats"),
                _ptr(order, "order", np.int64),
                _ptr(solve_log, "solve_log"),
                solve_log.shape[0],
                solve_log.shape[1],
                int(bool(start)),
            )
        )


def description_json(description: dict) -> str:
    """The description as the cache stores it (sorted keys: the same text for the same model)."""
    return json.dumps(description, sort_keys=True, indent=0)
