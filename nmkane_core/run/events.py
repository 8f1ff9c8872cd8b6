"""Events a system declares: named functions of the state and parameters, negative in the normal
motion (a vehicle touching the ground, a body leaving a surface, a pendulum passing the
vertical), and the times a run crosses them.

A system declares ``System(events=fn)`` where ``fn()`` (sympy inside: called only when the
compiled form is not cached yet) returns ``{name: expression}`` of the coordinates, speeds and
parameters (plain symbols or ``dynamicsymbols`` named like them); ``System(stop_events=...)``
says which of them end a run (default: all, as before this option existed).  A run may ask
otherwise: ``RunSettings.stop_at`` lists the events that end it (``[]``: none — every event is
recorded, the run goes on).

Every crossing is recorded (:func:`locate_crossings`): the sign changes of each event's value
over the output rows, each located in time to the integrator's accuracy by the Illinois
variant of regula falsi on the value at the state the run's own method reaches there
(:class:`~nmkane_core.run.dense.Dense`, which steps from the row before) — not on an
interpolation of the rows, so ``every`` does not coarsen it — and reported in
``summary["crossings"]`` ({name, t, direction}: ``rising`` from negative to ≥ 0, the event
firing; ``falling`` back).  A value ≥ 0 at the start is a rising crossing at t = 0.  A crossing
and recrossing between two output rows is not seen: ask ``every`` 1 for events faster than
the rows.

A run stops at the first rising crossing of an event in its stop set: the rows are cut there
and the located state is the last row (its energy, violations and outputs recomputed; forces
interpolated between the rows around it); status ``"event"``, ``summary["event"] = {name, t}``.
A run that failed (singular, diverged, ...) before that crossing keeps its failure; one that
failed after it ends with the event, which came first.  Maxima in the summary are recomputed
over the rows kept.

The expressions are compiled once into numpy source by :mod:`nmkane_core.kernel.events`.
"""

from __future__ import annotations

import numpy as np

from ..kernel.events import compile_events

__all__ = ["CROSSINGS_LISTED", "locate_crossings", "stop_at_event"]

#: crossings listed in a summary (more are counted in ``crossings_not_listed``)
CROSSINGS_LISTED = 1000
#: regula falsi's iterations (each a short re-integration); it stops earlier at a time
#: resolution of 1e-12 of the interval
_ITERATIONS = 60


def locate_crossings(system, params: dict, state_names, t: np.ndarray, x: np.ndarray, dense) -> list[dict]:
    """Every crossing of the system's events over the rows (t, x) in time order: {name, t,
    direction, row} with ``row`` the first row at or past it; located with ``dense`` (a
    :class:`~nmkane_core.run.dense.Dense` of the run)."""
    compiled = compile_events(system)
    if compiled is None or len(t) == 0:
        return []

    def value(name: str, xs: np.ndarray) -> np.ndarray:
        states = {k: xs[:, i] for i, k in enumerate(state_names)}
        return compiled.values(states, params)[name]

    found = []
    values = compiled.values({k: x[:, i] for i, k in enumerate(state_names)}, params)
    for name, g in values.items():
        on = np.nan_to_num(g, nan=-np.inf) >= 0.0
        if on[0]:
            found.append({"name": name, "t": float(t[0]), "direction": "rising", "row": 0})
        for k in np.flatnonzero(on[1:] != on[:-1]) + 1:
            if not (np.isfinite(g[k - 1]) and np.isfinite(g[k])):
                tc = float(t[k])
            else:
                tc = _regula_falsi(lambda s, n=name: float(value(n, dense.state(s)[None, :])[0]), t[k - 1], t[k])
            found.append({"name": name, "t": tc, "direction": "rising" if on[k] else "falling", "row": int(k)})
    return sorted(found, key=lambda c: (c["t"], c["name"]))


def _regula_falsi(f, t0: float, t1: float) -> float:
    """The zero of f in [t0, t1] (f(t0) < 0 ≤ f(t1) or the reverse) by the Illinois method."""
    a, b = float(t0), float(t1)
    fa, fb = f(a), f(b)
    if not (np.isfinite(fa) and np.isfinite(fb)) or (fa >= 0.0) == (fb >= 0.0):
        return b
    side = 0
    for _ in range(_ITERATIONS):
        c = b - fb * (b - a) / (fb - fa) if fb != fa else 0.5 * (a + b)
        if not a < c < b:
            c = 0.5 * (a + b)
        fc = f(c)
        if not np.isfinite(fc):
            return b
        if (fc >= 0.0) == (fb >= 0.0):  # the zero is in [a, c]
            b, fb = c, fc
            if side == -1:
                fa *= 0.5
            side = -1
        else:
            a, fa = c, fc
            if side == 1:
                fb *= 0.5
            side = 1
        if b - a <= 1e-12 * max(1.0, abs(b)) or fc == 0.0:
            break
    return b  # the first time at or past the zero: the event has fired there


def stop_at_event(crossings: list[dict], stop: frozenset[str]) -> dict | None:
    """The first rising crossing of an event in ``stop`` (the run ends there), or None."""
    for c in crossings:
        if c["direction"] == "rising" and c["name"] in stop:
            return c
    return None
