"""The rows a run reports, from the rows its loops wrote: cut at the event that stops it, or
made at the asked output times; and every event crossing, located (:mod:`.events`,
:mod:`.dense`).  Called by :func:`~nmkane_core.run.finish.finish` before the run's arrays are
named."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from ..integrate.job import LoopOutput
from .dense import Dense
from .events import CROSSINGS_LISTED, locate_crossings, stop_at_event
from .plan import Plan

__all__ = ["Timeline", "timeline"]


@dataclass
class Timeline:
    """What :func:`timeline` found: the crossings, the stop (a crossing, or None), warnings."""

    crossings: list[dict] = field(default_factory=list)
    stop: dict | None = None
    warnings: list[str] = field(default_factory=list)

    def into(self, summary: dict) -> None:
        """The crossings (and the stop) into a run's summary."""
        summary["crossings"] = [
            {k: c[k] for k in ("name", "t", "direction")} for c in self.crossings[:CROSSINGS_LISTED]
        ]
        summary["crossings_not_listed"] = max(0, len(self.crossings) - CROSSINGS_LISTED)
        summary["warnings"] += self.warnings


def timeline(plan: Plan, out: LoopOutput) -> tuple[LoopOutput, Timeline]:
    """(the rows to report, what was found) for a driver's finite rows ``out``."""
    found = Timeline()
    if plan.system.events is None and plan.output_times is None:
        return out, found
    job = plan.job()
    dense = Dense(job, out)
    if plan.system.events is not None:
        found.crossings = locate_crossings(plan.system, plan.params, plan.info.state_names, out.t, out.x, dense)
        found.stop = stop_at_event(found.crossings, plan.stop_events)
    if found.stop is not None:
        found.crossings = [c for c in found.crossings if c["t"] <= found.stop["t"]]
    end = found.stop["t"] if found.stop is not None else float(out.t[-1])
    if plan.output_times is not None:
        times = [t for t in plan.output_times if t <= end]
        if found.stop is not None and (not times or times[-1] < end):
            times.append(end)
        if len(times) < len(plan.output_times) and found.stop is None:
            found.warnings.append(
                f"the run ended at t = {end:.6g} s: {len(plan.output_times) - len(times)} of the asked output times "
                "lie beyond it"
            )
        rows = dense.states(times) if times else out.x[:1]
        out = _rows(job, out, np.asarray(times or [float(out.t[0])], float), rows, end if found.stop else out.t_end)
    elif found.stop is not None:
        k = found.stop["row"]
        t = np.append(out.t[:k], end) if k else out.t[:1]
        x = np.vstack([out.x[:k], dense.state(end)[None, :]]) if k else out.x[:1]
        out = _rows(job, out, t, x, end)
    if dense.fallbacks:
        found.warnings.append(
            f"{dense.fallbacks} state(s) between output rows were interpolated linearly: the run's method could not "
            "step there again (a singular matrix, or an equivalent model's rows)"
        )
    return out, found


def _rows(job, out: LoopOutput, t: np.ndarray, x: np.ndarray, t_end: float) -> LoopOutput:
    """``out`` with the rows (t, x), ending at ``t_end``: their energy, violations and, when
    reported, constraint forces recomputed by the run's model."""
    module = job.module
    E, V = np.empty(len(t)), np.empty((len(t), module.NV))
    module.diagnostics_rows(t, x, job.p, E, V)
    F, L = np.zeros((len(t), out.F.shape[1])), np.zeros((len(t), out.L.shape[1]))
    if out.F.shape[1]:
        Fm, Lm = np.empty((len(t), module.N)), np.empty((len(t), module.M))
        module.forces_rows(t, x, job.p, job.G, job.G1, job.G2, Fm, Lm)
        F[:, : module.N], L[:, : module.M] = Fm, Lm
    return replace(out, t=t, x=x, E=E, V=V, F=F, L=L, t_end=float(t_end))
