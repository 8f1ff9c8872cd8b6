"""Eigenvalues against a swept value, as a system declares it (`Stability`).

`sweep` gives the eigenvalues of the linearized motion
([`linearize`][nmkane_core.linearize]) at each value, `crossings` the values where
a real eigenvalue or a complex pair's real part changes sign (bisection), `state_at`
the full consistent state at a value.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from ..declare.stability import Stability
from ..declare.system import System
from ..errors import InputError
from ..kernel.built import built
from ..run.initial import initial_state
from ..run.registry import get_system
from .at_state import linearize

__all__ = ["sweep", "crossings", "state_at", "eigenvalues_at"]


def _declared(system: System | str) -> tuple[System, Stability]:
    system = get_system(system) if isinstance(system, str) else system
    st = system.stability
    if not isinstance(st, Stability):
        raise InputError("system", system.name, "a system that declares a stability sweep", "declares none")
    return system, st


def state_at(system: System | str, value: float, params: Mapping[str, float] | None = None) -> dict[str, float]:
    """The full consistent state of ``system`` at swept value ``value``."""
    system, st = _declared(system)
    _check_value(st, value)
    values = system.resolve_params(params or {})
    given = dict.fromkeys(built(system).independent, 0.0)
    given.update({k: float(v) for k, v in st.state(float(value), values).items()})
    _, full = initial_state(system, system.default_variant, values, given)
    return full


def _check_value(st: Stability, value) -> None:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not np.isfinite(float(value)):
        raise InputError(st.over, value, f"a finite {st.over} in {st.unit}", "not a finite number")


def eigenvalues_at(system: System | str, value: float, params: Mapping[str, float] | None = None) -> np.ndarray:
    """The eigenvalues at one swept value, sorted by real part, then imaginary part."""
    system, st = _declared(system)
    lin = linearize(system, state_at(system, value, params), params, keep=st.keep)
    return np.array(sorted(lin.eigenvalues, key=lambda z: (round(z.real, 9), z.imag)))


def sweep(
    system: System | str, values: Iterable[float] | None = None, params: Mapping[str, float] | None = None
) -> list[dict]:
    """One row per value: ``{"value": v, "eigenvalues": [[re, im], ...]}`` (sorted by real part).

    ``values``: the swept values (default: the system's declared range)."""
    system, st = _declared(system)
    if values is None:
        values = np.linspace(st.start, st.stop, st.count)
    rows = []
    for v in values:
        _check_value(st, v)
        ev = eigenvalues_at(system, float(v), params)
        rows.append({"value": float(v), "eigenvalues": [[float(z.real), float(z.imag)] for z in ev]})
    return rows


def _unstable(ev: np.ndarray, tol: float = 1e-9) -> tuple[int, int]:
    """(eigenvalues of a complex pair with re > 0, real eigenvalues > 0)."""
    cplx = sum(1 for z in ev if abs(z.imag) > tol and z.real > tol)
    real = sum(1 for z in ev if abs(z.imag) <= tol and z.real > tol)
    return cplx, real


def crossings(
    system: System | str, rows: list[dict], params: Mapping[str, float] | None = None, xtol: float = 1e-11
) -> list[dict]:
    """Where the number of eigenvalues with a positive real part changes between rows of
    `sweep`, refined by bisection (the kind: a complex pair's or a real one's crossing):
    ``[{"name", "kind" ("complex"|"real"), "value", "reference"}]`` (``name`` and
    ``reference`` from the declaration, None when it has none)."""
    system, st = _declared(system)
    out = []
    evs = [np.array([complex(a, b) for a, b in r["eigenvalues"]]) for r in rows]
    for i in range(len(rows) - 1):
        a, b = rows[i]["value"], rows[i + 1]["value"]
        ua, ub = _unstable(evs[i]), _unstable(evs[i + 1])
        total = sum(ub) - sum(ua)
        if total == 0:  # e.g. two unstable real eigenvalues becoming an unstable pair: no crossing
            continue
        dc = ub[0] - ua[0]
        kind = "complex" if dc != 0 and (dc > 0) == (total > 0) else "real"
        lo, hi, flo = a, b, sum(ua)
        while hi - lo > xtol * max(1.0, abs(hi)):
            mid = 0.5 * (lo + hi)
            if sum(_unstable(eigenvalues_at(system, mid, params))) == flo:
                lo = mid
            else:
                hi = mid
        name = st.names.get(kind)
        out.append({"name": name, "kind": kind, "value": 0.5 * (lo + hi), "reference": st.reference.get(name or "")})
    return out
