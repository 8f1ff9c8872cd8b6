"""A driver's output made into a :class:`~nmkane_core.run.result.Run`: named arrays, how the run
ended (:mod:`nmkane_core.run.endings`), the system's events, and the summary — one
:class:`~nmkane_core.schema.RunSummary`, every number finite.

Guarantees: rows from the first one whose state, energy, violations or outputs are not
finite on are cut (the run then ends ``diverged``), and a summary number that overflowed is
reported as ±1.8e308 and named in a warning, so the document is valid JSON of the schema.
"""

from __future__ import annotations

import json
import math
import sys
from dataclasses import replace

import numpy as np

from ..integrate.job import LoopOutput
from ..kernel.built import built
from ..kernel.constants import (
    ROBUST_LEAVE_KE,
    STATS_MAX_DRIFT,
    STATS_MAX_LEAVE,
    STATS_MAX_STAB,
    STATS_RCOND_C,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_VIOL,
    STATUS_DIVERGED,
    STATUS_J2_SINGULAR,
)
from ..schema import LIMITS, RunSummary
from .endings import OVERFLOW, ending
from .forces import add_point_forces
from .partition import partition
from .plan import Plan
from .result import Run
from .solvelog import inconsistency, robust_summary, solve_switches
from .timeline import timeline

__all__ = ["finish"]

FLOAT_MAX = sys.float_info.max


def finish(plan: Plan, out: LoopOutput, wall: float, kernel_load_s: float = 0.0) -> Run:
    """The :class:`Run` of a driver's output (``wall``: integration wall time, s)."""
    mod = built(plan.system).module(plan.variant)
    out, _, overflow = _finite_rows(plan, out, _outputs(plan, mod, out))
    status, message = _ending(plan, out, overflow)
    out, found = timeline(plan, out)  # the event that stops it, the asked output times (run.timeline)
    outputs = _outputs(plan, mod, out)
    notes = _finite_forces(out) + _unknown_multipliers(out)
    run = _arrays(plan, out, outputs)
    run.summary = _summary(plan, out, status, message, wall, kernel_load_s)
    run.summary["warnings"] += notes + add_point_forces(plan, run, out)
    found.into(run.summary)
    if found.stop is not None:
        _stopped_by_event(run, found.stop)
    run.summary = _validated(run.summary)
    return run


def _stopped_by_event(run: Run, stop: dict) -> None:
    """The summary of a run cut at the event that stopped it (:mod:`nmkane_core.run.events`):
    status ``event``, its maxima over the rows kept (the loops' are over every step; the
    multipliers' and point forces' are over the rows already)."""
    name, tc, s = stop["name"], stop["t"], run.summary
    if run.energy is not None:
        s["max_abs_energy_drift"] = float(np.max(np.abs(run.energy - run.energy[0])))
        s["final_energy_drift"] = float(run.energy[-1] - run.energy[0])
    s["max_abs_violation"] = {key: float(np.max(np.abs(v))) for key, v in run.violation.items()}
    s.update(status="event", event={"name": name, "t": tc}, t_end=tc)
    s["message"] = (
        f"event {name!r} at t = {tc:.6g} s"
        + (" (already at the start)" if stop["row"] == 0 else "")
        + f": the run stopped there ({name} reached zero; located to the integrator's accuracy)"
    )


def _outputs(plan: Plan, mod, out: LoopOutput) -> np.ndarray:
    """The model's extra outputs (``MechanicalModel.outputs``) on every row."""
    O = np.empty((out.x.shape[0], mod.NO))
    if mod.NO:
        mod.outputs_rows(out.t, out.x, plan.p, O)
    return O


def _finite_rows(plan: Plan, out: LoopOutput, O: np.ndarray) -> tuple[LoopOutput, np.ndarray, bool]:
    """The loops stop when the state stops being finite; its energy, constraint violations or
    outputs can overflow first (huge speeds): keep the rows before, and say so (True)."""
    good = np.isfinite(out.t) & np.isfinite(out.x).all(axis=1) & np.isfinite(out.V).all(axis=1)
    good &= np.isfinite(O).all(axis=1)
    if plan.info.has_energy:
        good &= np.isfinite(out.E)
    if good.all():
        return out, O, False
    keep = max(1, int(np.argmin(good)))  # row 0 is checked finite by plan.resolve
    cut = replace(
        out,
        status=STATUS_DIVERGED,
        stop=None,
        t=out.t[:keep],
        x=out.x[:keep],
        E=out.E[:keep],
        V=out.V[:keep],
        F=out.F[:keep],
        L=out.L[:keep],
        t_end=float(out.t[keep - 1]),
    )
    _finite_stats(cut)
    return cut, O[:keep], True


def _finite_forces(out: LoopOutput) -> list[str]:
    """Rows whose constraint forces are not finite (a state where J2 is singular: the run's last,
    say) get 0, and a warning says when."""
    if not out.F.shape[1]:
        return []
    bad = ~(np.isfinite(out.F).all(axis=1) & np.isfinite(out.L).all(axis=1))
    if not bad.any():
        return []
    out.F[bad], out.L[bad] = 0.0, 0.0
    times = out.t[bad]
    return [
        f"constraint forces are not defined at {int(bad.sum())} output row(s) (t = {times[0]:.6g}"
        + (f" … {times[-1]:.6g}" if times.size > 1 else "")
        + " s: a singular constraint matrix); reported as 0 there"
    ]


def _unknown_multipliers(out: LoopOutput) -> list[str]:
    return [
        f"multipliers from t = {a:.6g} s to {b:.6g} s are reported as 0: the run went on with an "
        "equivalent model there, whose equations are others (the constraint forces are the same)"
        for a, b in out.unknown_multipliers
    ]


def _finite_stats(out: LoopOutput) -> None:
    """Maxima of a diverged run recomputed over the rows kept when they overflowed."""
    stats = out.stats
    if not np.isfinite(stats[STATS_MAX_DRIFT]):
        E = out.E
        stats[STATS_MAX_DRIFT] = float(np.max(np.abs(E - E[0]))) if np.isfinite(E).all() else 0.0
    viol = stats[STATS_VIOL:]
    bad = ~np.isfinite(viol)
    if bad.any():
        viol[bad] = np.max(np.abs(out.V), axis=0)[bad]


def _ending(plan: Plan, out: LoopOutput, overflow: bool) -> tuple[str, str]:
    j2 = out.status == STATUS_J2_SINGULAR
    facts = {
        "rcond_c": out.stats[STATS_RCOND_C],
        "steps": out.steps,
        "method": plan.integrator.name,
        "t_final": plan.t_final,
        "t_end": out.t_end,
        "matrix": "J2" if j2 else "T",
        "rcond": out.stats[STATS_RCOND_J2] if j2 else out.stats[STATS_RCOND_T],
        "rcond_min": plan.rcond_min,
        "projection": plan.projection.name,
        "max_steps": LIMITS["max_steps"],
        "max_rows": LIMITS["max_rows"],
        **_left_constraints(plan, out),
        **inconsistency(plan.info, out),
        **_drift(plan, out),
    }
    if overflow:
        return OVERFLOW.status, OVERFLOW.message.format(**facts)
    hint = plan.system.singular_hints.get(plan.variant, "")
    return ending(out.status, out.stop, facts, out.fail_msg, hint)


def _drift(plan: Plan, out: LoopOutput) -> dict:
    """Which bound a drifted run passed (STATUS_DRIFTED): the energy drift, or the violation."""
    stats, info = out.stats, plan.info
    if stats[STATS_MAX_DRIFT] > plan.drift_limit:
        return {"drift": f"|E − E0| reached {stats[STATS_MAX_DRIFT]:.3g} J", "bound": plan.drift_limit}
    viol = stats[STATS_VIOL:]
    i = int(np.argmax(viol)) if viol.size else 0
    name = info.viol_names[i] if viol.size else "?"
    return {
        "drift": f"the violation of {name} reached {viol[i] if viol.size else 0.0:.3g}",
        "bound": plan.violation_limit,
    }


def _left_constraints(plan: Plan, out: LoopOutput) -> dict:
    """What carried the motion off its constraints (STATUS_LEFT_CONSTRAINTS): the projection's
    speed correction, or the Baumgarte terms' velocity change in a step."""
    leave, stab = out.stats[STATS_MAX_LEAVE], out.stats[STATS_MAX_STAB]
    if leave > ROBUST_LEAVE_KE:
        return {
            "correction": f"the {plan.projection.name} projection's speed correction",
            "share": leave,
            "cure": "try a smaller dt",
        }
    return {
        "correction": "the velocity change the Baumgarte terms (Γ, Γ1, Γ2) made",
        "share": stab,
        "cure": "the post-step projection keeps the state on its branch (projection yoon), or try another dt",
    }


def _arrays(plan: Plan, out: LoopOutput, O: np.ndarray) -> Run:
    """The run's arrays by name: the state (with the outputs), energy, violations."""
    md = plan.info
    state = {name: out.x[:, i].copy() for i, name in enumerate(md.state_names)}
    for i, name in enumerate(md.outputs):
        state[name] = O[:, i].copy()  # contiguous, like every other array
    names = built(plan.system).state_names  # the system's order (the same in every variant), then the outputs
    state = {k: state[k] for k in names if k in state} | {k: v for k, v in state.items() if k not in names}
    return Run(
        system=plan.system.name,
        settings=plan.settings,
        t=out.t.copy(),
        state=state,
        energy=out.E.copy() if md.has_energy else None,
        violation={k: out.V[:, i].copy() for i, k in enumerate(md.viol_names)},
        summary={},
        constraint_forces={k: out.F[:, i].copy() for i, k in enumerate(md.u)} if out.F.shape[1] else {},
        multipliers={k: out.L[:, i].copy() for i, k in enumerate(md.constraint_names)} if out.F.shape[1] else {},
    )


def _summary(plan: Plan, out: LoopOutput, status: str, message: str, wall: float, load: float) -> dict:
    md, stats = plan.info, out.stats
    E = out.E if md.has_energy else None
    mod = built(plan.system).module(plan.variant)
    paper_first = plan.solve != 1 and plan.max_rank == mod.M and mod.M <= mod.N
    switches = sorted(out.switches + solve_switches(mod, md, plan.order, paper_first, out), key=lambda s: s["t"])
    return {
        "status": status,
        "message": message,
        "steps": int(out.steps),
        "rhs_evals": int(out.evals),
        "wall_time_s": wall,
        "kernel_load_s": load,
        "kernel_tier": "compiled",
        "t_end": float(out.t_end),
        "max_abs_violation": {k: float(stats[STATS_VIOL + i]) for i, k in enumerate(md.viol_names)},
        "max_abs_energy_drift": float(stats[STATS_MAX_DRIFT]) if E is not None else None,
        "final_energy_drift": float(E[-1] - E[0]) if E is not None else None,
        "min_rcond": {
            "J2": float(stats[STATS_RCOND_J2]),
            "T": float(stats[STATS_RCOND_T]),
            **({"C": float(stats[STATS_RCOND_C])} if mod.KN else {}),
        },
        "max_abs_multiplier": (
            {k: float(np.abs(out.L[:, i]).max(initial=0.0)) for i, k in enumerate(md.constraint_names)}
            if out.F.shape[1]
            else {}
        ),
        "warnings": list(plan.warnings),
        "switches": switches,
        "initial_correction": dict(plan.initial_correction),
        "robust_solve": robust_summary(mod, out, plan.solve),
        "bounds": {
            "energy_drift": plan.drift_limit if math.isfinite(plan.drift_limit) else None,
            "violation": plan.violation_limit if math.isfinite(plan.violation_limit) else None,
        },
        "partition": _partition(plan),
    }


def _partition(plan: Plan) -> dict:
    """The partition the run started with (summary ``partition``)."""
    part = partition(plan.system, plan.variant)
    return {
        "u_independent": list(part.u_independent),
        "q_dependent": list(part.q_dependent),
        "chosen": "declared" if part.declared else "pivoting",
    }


def _validated(summary: dict) -> dict:
    """The summary through the schema (:class:`RunSummary`), numbers that overflowed made the
    largest finite ones (JSON has no infinity) and named in a warning."""
    fixed: list[str] = []
    try:  # the usual case, all finite, checked in C (~10 µs; the walk below is slower)
        json.dumps(summary, allow_nan=False)
    except (TypeError, ValueError):
        summary = _finite_copy(summary, "", fixed)
    if fixed:
        summary["warnings"] = [
            *summary.get("warnings", []),
            "overflowed to infinity, reported as ±1.8e308: " + ", ".join(fixed),
        ]
    return RunSummary.model_validate(summary).model_dump(mode="json", by_alias=True)


def _finite_copy(value, path: str, fixed: list[str]):
    if isinstance(value, float) and not math.isfinite(value):
        fixed.append(path)
        return -FLOAT_MAX if value < 0 else FLOAT_MAX
    if isinstance(value, dict):
        return {k: _finite_copy(v, f"{path}.{k}" if path else str(k), fixed) for k, v in value.items()}
    if isinstance(value, list):
        return [_finite_copy(v, f"{path}[{i}]", fixed) for i, v in enumerate(value)]
    return value
