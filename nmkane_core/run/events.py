"""Events a system declares: named functions of the state and parameters that end a run
when they reach zero (a vehicle touching the ground, a body leaving a surface).

A system declares ``System(events=fn)`` where ``fn()`` (sympy inside: called only when the
compiled form is not cached yet) returns ``{name: expression}``; each expression is of the
coordinates, speeds and parameters (plain symbols or ``dynamicsymbols`` named like them),
negative during the normal motion.  The event fires at the first time its expression is
≥ 0 (at the start, if it already is there).

How a run stops (:func:`apply_events`, called on every finished run): the expressions are
evaluated on the output rows after the integration, and the run is cut at the first
crossing, the crossing time found by linear interpolation between the two rows around it,
where an interpolated last row (state, energy and violations) is put.  The run's status is
then ``"event"``, with ``summary["event"] = {"name", "t"}``.  A run that failed (singular,
diverged, ...) before the first crossing keeps its failure; one that failed after it (a
vehicle lying flat can make its contact geometry singular) ends with the event, which came
first.  The crossing time is as fine as the output rows (``every``): a crossing and
recrossing between two rows is not seen.  Maxima in the summary (constraint violations,
energy drift) are recomputed over the rows kept.

The expressions are compiled once into numpy source by :mod:`nmkane_core.kernel.events`.
"""

from __future__ import annotations

import numpy as np

from ..kernel.events import compile_events

__all__ = ["apply_events", "first_crossing"]


def first_crossing(t: np.ndarray, values: dict[str, np.ndarray]) -> tuple[str, float, int] | None:
    """(event name, time, row index k ≥ 0 of the first row at or past it) of the earliest
    crossing over rows ``t``, or None.  Non-finite values count as not crossed."""
    best = None
    for name, g in values.items():
        hit = np.flatnonzero(np.nan_to_num(g, nan=-np.inf) >= 0.0)
        if hit.size == 0:
            continue
        k = int(hit[0])
        if k == 0:
            tc = float(t[0])
        else:
            g0, g1 = float(g[k - 1]), float(g[k])
            frac = g0 / (g0 - g1) if g1 != g0 else 1.0
            tc = float(t[k - 1] + min(1.0, max(0.0, frac)) * (t[k] - t[k - 1]))
        if best is None or tc < best[1]:
            best = (name, tc, k)
    return best


def _max_point_forces(components: dict[str, np.ndarray]) -> dict[str, float]:
    """The largest |R| of each force over the rows (components NAME.LABEL, orthonormal axes)."""
    squares: dict[str, np.ndarray] = {}
    for key, v in components.items():
        name = key.split(".", 1)[0]
        squares[name] = squares.get(name, 0.0) + np.asarray(v, float) ** 2
    return {name: float(np.sqrt(np.max(s))) for name, s in squares.items()}


def apply_events(run, system):
    """Cut a finished :class:`~nmkane_core.run.result.Run` at its system's first event, in place,
    and return it (unchanged when no event is declared or none fired).  A failed run's rows
    end at its last good state, so an event found in them came before the failure.
    ``system``: the run's :class:`~nmkane_core.declare.system.System`."""
    compiled = compile_events(system)
    if compiled is None or len(run.t) == 0:
        return run
    params = system.resolve_params(run.settings.get("params", {}))
    found = first_crossing(run.t, compiled.values(run.state, params))
    if found is None:
        return run
    name, tc, k = found
    if k == 0:
        keep = {key: v[:1].copy() for key, v in run.state.items()}
        cut = lambda a: a[:1].copy()  # noqa: E731
    else:
        t0, t1 = run.t[k - 1], run.t[k]
        a = 0.0 if t1 == t0 else (tc - t0) / (t1 - t0)

        def cut(arr):
            return np.append(arr[:k], (1 - a) * arr[k - 1] + a * arr[k])

        keep = {key: cut(v) for key, v in run.state.items()}
    run.t = np.append(run.t[: max(k, 1)], tc) if k else run.t[:1].copy()
    run.state = keep
    if run.energy is not None:
        run.energy = cut(run.energy)
        run.summary["max_abs_energy_drift"] = float(np.max(np.abs(run.energy - run.energy[0])))
        run.summary["final_energy_drift"] = float(run.energy[-1] - run.energy[0])
    run.violation = {key: cut(v) for key, v in run.violation.items()}
    run.constraint_forces = {key: cut(v) for key, v in run.constraint_forces.items()}
    run.multipliers = {key: cut(v) for key, v in run.multipliers.items()}
    run.point_forces = {key: cut(v) for key, v in run.point_forces.items()}
    run.summary["max_abs_violation"] = {key: float(np.max(np.abs(v))) for key, v in run.violation.items()}
    if run.multipliers:
        run.summary["max_abs_multiplier"] = {key: float(np.max(np.abs(v))) for key, v in run.multipliers.items()}
    if run.point_forces:
        run.summary["max_abs_point_force"] = _max_point_forces(run.point_forces)
    run.summary["status"] = "event"
    run.summary["event"] = {"name": name, "t": tc}
    run.summary["t_end"] = tc
    run.summary["message"] = (
        f"event {name!r} at t = {tc:.6g} s"
        + (" (already at the start)" if k == 0 else "")
        + f": the run stopped there ({name} reached zero; found on the output rows, interpolated)"
    )
    return run
