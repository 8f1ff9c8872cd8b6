"""A finished run (:class:`Run`: arrays by name and the summary, CSV/JSON/NPZ writers), and
:func:`finish`, which builds it from what a loop driver returns (:class:`LoopOutput`).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from ..kernel.built import built
from ..kernel.interface import (
    STATS_MAX_DRIFT,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_VIOL,
    STATUS_DIVERGED,
    STATUS_J2_SINGULAR,
    STATUS_OK,
    STATUS_PROJECTION_FAILED,
    STATUS_T_SINGULAR,
)
from ..schema import LIMITS, RunResult, RunSummary
from .plan import Plan

__all__ = ["Run", "LoopOutput", "finish"]


@dataclass
class Run:
    """A finished run: arrays by name and the summary (convert with :meth:`document`)."""

    system: str
    settings: dict
    t: np.ndarray
    state: dict[str, np.ndarray]
    energy: np.ndarray | None
    violation: dict[str, np.ndarray]
    summary: dict

    @property
    def status(self) -> str:
        return self.summary["status"]

    def document(self, id: str | None = None) -> RunResult:
        return RunResult(
            id=id,
            system=self.system,
            settings=self.settings,
            t=self.t.tolist(),
            state={k: v.tolist() for k, v in self.state.items()},
            energy=None if self.energy is None else self.energy.tolist(),
            violation={k: v.tolist() for k, v in self.violation.items()},
            summary=RunSummary(**self.summary),
        )

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t, **self.state}
        if self.energy is not None:
            cols["energy"] = self.energy
        cols.update({f"violation_{k}": v for k, v in self.violation.items()})
        return cols

    def to_csv(self) -> str:
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for row in zip(*[c.tolist() for c in cols.values()], strict=True):
            w.writerow([repr(v) for v in row])
        return buf.getvalue()

    def save(self, path: str) -> None:
        """Write ``.json`` (the run document), ``.csv`` or ``.npz``."""
        if path.endswith(".json"):
            with open(path, "w") as f:
                f.write(self.document().model_dump_json(by_alias=True))
        elif path.endswith(".csv"):
            with open(path, "w") as f:
                f.write(self.to_csv())
        elif path.endswith(".npz"):
            import json

            arrays: dict = {
                **self.columns(),
                "summary": json.dumps(self.summary),
                "settings": json.dumps(self.settings),
            }
            np.savez_compressed(path, **arrays)
        else:
            raise InputError("out", path, "a file name ending in .json, .csv or .npz", "unknown format")


@dataclass
class LoopOutput:
    """What a loop driver returns: the rows it computed and how the integration ended."""

    status: int  # a STATUS_* code (nmkane_core.kernel.interface)
    stop: str | None  # "timeout" | "cancelled" | "max_steps" | "max_rows" | None
    t: np.ndarray
    x: np.ndarray
    E: np.ndarray
    V: np.ndarray
    stats: np.ndarray  # STATS_* layout (nmkane_core.kernel.interface)
    steps: int
    evals: int  # right-hand-side evaluations
    t_end: float
    switches: list[dict] = field(default_factory=list)
    fail_msg: str | None = None


def _finite_stats(stats: np.ndarray, out: LoopOutput) -> None:
    """Maxima of a diverged run recomputed over the rows kept when they overflowed."""
    if not np.isfinite(stats[STATS_MAX_DRIFT]):
        E = out.E
        stats[STATS_MAX_DRIFT] = float(np.max(np.abs(E - E[0]))) if np.isfinite(E).all() else 0.0
    viol = stats[STATS_VIOL:]
    bad = ~np.isfinite(viol)
    if bad.any():
        viol[bad] = np.max(np.abs(out.V), axis=0)[bad]


def finish(plan: Plan, mod, out: LoopOutput, wall: float) -> Run:
    """The :class:`Run` of a driver's output: named arrays, the status and its message, the summary."""
    md = plan.info
    system = plan.system
    code, stop, t_end, stats = out.status, out.stop, out.t_end, out.stats
    if code == STATUS_OK and stop is None:
        status = "ok"
        message = f"completed: {out.steps:,} steps of {plan.integrator.name} to t = {plan.t_final:g} s"
    elif code == STATUS_OK and stop in ("timeout", "cancelled"):
        status = "timeout"
        message = (
            f"stopped at t = {t_end:.6g} s: {'wall-time limit reached' if stop == 'timeout' else 'cancelled'}"
            f"; results up to there are kept"
        )
    elif code in (STATUS_J2_SINGULAR, STATUS_T_SINGULAR):
        status = "singular"
        which = "J2" if code == STATUS_J2_SINGULAR else "T"
        rc = stats[STATS_RCOND_J2] if code == STATUS_J2_SINGULAR else stats[STATS_RCOND_T]
        message = (
            f"{which} became singular or ill-conditioned after t = {t_end:.6g} s "
            f"(reciprocal condition estimate {rc:.3g} ≤ rcond_min = {plan.rcond_min:g}); "
            f"the run stopped there and keeps the last good state"
        )
        hint = system.singular_hints.get(plan.variant)
        if hint:
            message += f" — {hint}"
    elif code == STATUS_DIVERGED:
        status = "diverged"
        message = (
            f"the state or its derivative stopped being finite after t = {t_end:.6g} s; the run "
            f"stopped and keeps the last finite state (an unstable step: try a smaller dt or gains of "
            f"smaller magnitude; or the motion reached a point where the model's expressions are not "
            f"defined — a square root of a negative number, a zero denominator — e.g. the end of the "
            f"branch of a constraint nonlinear in the speeds)"
        )
    elif code == STATUS_PROJECTION_FAILED:
        status = "failed"
        message = (
            f"the {plan.projection.name} projection met a singular correction matrix after "
            f"t = {t_end:.6g} s; the run stopped there"
        )
    else:
        status = "failed"
        if out.fail_msg:
            message = out.fail_msg
        elif stop == "max_steps":
            message = f"the step budget ({LIMITS['max_steps']:,}) was used up at t = {t_end:.6g} s"
        elif stop == "max_rows":
            message = (
                f"the output reached its limit of {LIMITS['max_rows']:,} rows at t = {t_end:.6g} s "
                f"(the step size kept shrinking — a singularity ahead? — or use a larger every); "
                f"the rows up to there are kept"
            )
        else:
            message = (
                f"the step size fell below its minimum at t = {t_end:.6g} s: the solution cannot be "
                f"continued there (a blow-up, or a point where the model's expressions are not defined — "
                f"a square root of a negative number, a zero denominator — e.g. the end of the branch of "
                f"a constraint nonlinear in the speeds); the rows up to there are kept"
            )
    x = out.x
    O = np.empty((x.shape[0], mod.NO))
    if mod.NO:
        mod.outputs_rows(out.t, x, plan.p, O)
    # The loops stop when the state stops being finite; its energy, constraint violations or
    # outputs can overflow first (huge speeds): keep the rows before, end the run as diverged.
    good = np.isfinite(out.t) & np.isfinite(x).all(axis=1) & np.isfinite(out.V).all(axis=1) & np.isfinite(O).all(axis=1)
    if md.has_energy:
        good &= np.isfinite(out.E)
    if not good.all():
        keep = max(1, int(np.argmin(good)))  # row 0 is checked finite by plan.resolve
        t_end = float(out.t[keep - 1])
        out = LoopOutput(
            status=STATUS_DIVERGED,
            stop=None,
            t=out.t[:keep],
            x=x[:keep],
            E=out.E[:keep],
            V=out.V[:keep],
            stats=stats,
            steps=out.steps,
            evals=out.evals,
            t_end=t_end,
            switches=out.switches,
            fail_msg=out.fail_msg,
        )
        x, O = out.x, O[:keep]
        status = "diverged"
        message = (
            f"the energy, a constraint violation or an output stopped being finite (overflow) after "
            f"t = {t_end:.6g} s; the run stopped and keeps the rows up to there (try smaller initial "
            f"speeds, a smaller dt or gains of smaller magnitude)"
        )
        _finite_stats(stats, out)
    state = {name: x[:, i].copy() for i, name in enumerate(md.state_names)}
    if mod.NO:
        for i, name in enumerate(md.outputs):
            state[name] = O[:, i].copy()  # contiguous, like every other array
    state = {k: state[k] for k in built(system).state_names if k in state}
    viol_names = md.viol_names
    violation = {k: out.V[:, i].copy() for i, k in enumerate(viol_names)}
    has_energy = md.has_energy
    energy = out.E.copy() if has_energy else None
    summary = {
        "status": status,
        "message": message,
        "steps": int(out.steps),
        "rhs_evals": int(out.evals),
        "wall_time_s": wall,
        "t_end": float(t_end),
        "max_abs_violation": {k: float(stats[STATS_VIOL + i]) for i, k in enumerate(viol_names)},
        "max_abs_energy_drift": float(stats[STATS_MAX_DRIFT]) if has_energy else None,
        "final_energy_drift": float(energy[-1] - energy[0]) if energy is not None else None,
        "min_rcond": {"J2": float(stats[STATS_RCOND_J2]), "T": float(stats[STATS_RCOND_T])},
        "warnings": list(plan.warnings),
        "switches": out.switches,
        "initial_correction": dict(plan.initial_correction),
    }
    return Run(
        system=system.name,
        settings=plan.settings,
        t=out.t.copy(),
        state=state,
        energy=energy,
        violation=violation,
        summary=summary,
    )
