"""The adaptive driver: ``integrate_adaptive`` called until t_final, a row or step budget, or a stop.

Each call writes at most :data:`ROWS_PER_CALL` rows and makes at most
:data:`ATTEMPTS_PER_CALL` attempts; between calls the driver updates the progress bar,
checks the time limit and cancellation, bounds the output (a step size collapsing toward a
singularity cannot fill memory) and lets the switcher change the model.
"""

from __future__ import annotations

import numpy as np

from ..kernel.constants import STATUS_BUDGET, STATUS_FAILED, STATUS_J2_SINGULAR, STATUS_OK, STATUS_T_SINGULAR
from ..schema import LIMITS
from .calls import Rows, SolveState, Stopper, adaptive_args, forces_at, initial_stats, rows_for
from .job import Job, LoopOutput
from .switching import Switcher

__all__ = ["ATTEMPTS_PER_CALL", "ROWS_PER_CALL", "run_adaptive"]

ROWS_PER_CALL = 4096  # output buffer of one adaptive call: the most rows a call adds
ATTEMPTS_PER_CALL = 200_000


class _Chunks:
    """The rows of a run, chunk by chunk (the first row: the initial state)."""

    def __init__(self, job: Job, first: Rows):
        self.parts = [first]
        self.sizes = [1]
        self.count = 1

    def add(self, rows: Rows, n: int) -> None:
        self.parts.append(rows)
        self.sizes.append(n)
        self.count += n

    def last_t(self) -> float:
        """The time of the last row kept (a call that ended before its first row adds none: its
        buffer holds no row, and reading it read whatever the memory held)."""
        part, n = next((r, n) for r, n in zip(reversed(self.parts), reversed(self.sizes), strict=True) if n > 0)
        return float(part.t[n - 1])

    def rows(self) -> Rows:
        """Every row in one :class:`Rows`."""
        out = Rows(0, 0, 0)
        for name in ("t", "x", "E", "V", "F", "L"):
            setattr(
                out, name, np.concatenate([getattr(r, name)[:n] for r, n in zip(self.parts, self.sizes, strict=True)])
            )
        return out


def run_adaptive(job: Job, bar, stopper: Stopper) -> LoopOutput:
    """Integrate ``job`` with its embedded tableau, the step following rtol and atol."""
    stats, E0, V0 = initial_stats(job, job.module, job.p)
    first = rows_for(job, job.module, 1)
    first.t[0], first.x[0], first.E[0], first.V[0] = 0.0, job.x0, E0, V0
    solve = SolveState(job, job.module)
    if job.forces:
        forces_at(job, job.module, job.p, 0.0, job.x0, first, 0, solve)
    chunks = _Chunks(job, first)
    x = job.x0.copy()
    t, h = 0.0, min(job.dt, job.t_final)
    accepted = attempts = 0
    status, stop = STATUS_OK, None
    sw = Switcher(job)
    while t < job.t_final:
        size = sw.SWITCHED_CHUNK if sw.switched else ROWS_PER_CALL
        budget = int(min(sw.SWITCHED_CHUNK if sw.switched else ATTEMPTS_PER_CALL, LIMITS["max_steps"] - attempts))
        rows = rows_for(job, sw.module, size)
        args = adaptive_args(
            job,
            sw.p,
            x,
            rows,
            stats,
            t=t,
            h=h,
            max_steps=budget,
            accepted=accepted,
            rcond_min=sw.threshold,
            solve=solve,
        )
        status, t, h, nrow, accepted, att, pending = sw.module.integrate_adaptive(*args)
        solve.collect(stats)
        sw.h = h
        if pending >= 0:  # the call's last row: no step of this call started from it
            forces_at(job, sw.module, sw.p, float(rows.t[pending]), rows.x[pending], rows, pending, solve)
        attempts += att
        chunks.add(rows, nrow)
        bar.update(t)
        if chunks.count >= LIMITS["max_rows"] and t < job.t_final:
            status, stop = STATUS_FAILED, "max_rows"
            break
        if status in (STATUS_J2_SINGULAR, STATUS_T_SINGULAR) and sw.leave(t, x, chunks.count):
            status = STATUS_OK
            continue
        if status == STATUS_BUDGET:
            status = STATUS_OK
            if attempts >= LIMITS["max_steps"]:
                status, stop = STATUS_FAILED, "max_steps"
                break
        if status != STATUS_OK:
            break
        sw.maybe_return(t, x, chunks.count)
        stop = stopper.reason()
        if stop and t < job.t_final:
            break
        stop = None
    _keep_last(job, chunks, t, x, solve)
    out = chunks.rows()
    sw.finish(chunks.count, out, stats)
    return LoopOutput(
        status=status,
        stop=stop,
        t=out.t,
        x=out.x,
        E=out.E,
        V=out.V,
        F=out.F,
        L=out.L[:, : job.module.M],
        stats=stats,
        steps=accepted,
        evals=attempts * job.method.stages,  # type: ignore[union-attr]
        t_end=t,
        switches=sw.switches,
        unknown_multipliers=sw.unknown_multipliers,
        solve_log=solve.records,
        solve_log_dropped=solve.dropped,
    )


def _keep_last(job: Job, chunks: _Chunks, t: float, x: np.ndarray, solve: SolveState) -> None:
    """Keep the last good state as a row even when thinning (``every``) skipped it."""
    if chunks.last_t() < t - 1e-12 * max(1.0, t):
        rows = rows_for(job, job.module, 1)
        rows.t[0], rows.x[0] = t, x
        job.module.diagnostics_rows(rows.t, rows.x, job.p, rows.E, rows.V)
        if job.forces:
            forces_at(job, job.module, job.p, t, x, rows, 0, solve)
        chunks.add(rows, 1)
