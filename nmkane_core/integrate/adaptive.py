"""The adaptive driver: ``integrate_adaptive`` called until t_final, a row or step budget, or a stop.

Each call writes at most :data:`ROWS_PER_CALL` rows and makes at most
:data:`ATTEMPTS_PER_CALL` attempts; between calls the driver updates the progress bar,
checks the time limit and cancellation, bounds the output (a step size collapsing toward a
singularity cannot fill memory) and lets the switcher change the model.
"""

from __future__ import annotations

import numpy as np

from ..kernel.constants import STATUS_BUDGET, STATUS_FAILED, STATUS_OK
from ..schema import LIMITS
from .calls import Rows, SolveState, Stopper, adaptive_args, forces_at, rows_for
from .driver import CompiledDriver
from .job import Job, LoopOutput

__all__ = ["ATTEMPTS_PER_CALL", "ROWS_PER_CALL", "AdaptiveDriver"]

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


class AdaptiveDriver(CompiledDriver):
    """``integrate_adaptive`` until t_final: each call fills a new buffer of rows (the rows are not
    known ahead), within a budget of attempts; the output is bounded by ``LIMITS``."""

    def __init__(self, job: Job, bar, stopper: Stopper):
        super().__init__(job, bar, stopper)
        first = rows_for(job, job.module, 1)
        first.t[0], first.x[0], first.E[0], first.V[0] = 0.0, job.x0, self.E0, self.V0
        if job.forces:
            forces_at(job, job.module, job.p, 0.0, job.x0, first, 0, self.solve)
        self.chunks = _Chunks(job, first)
        self.t, self.h = 0.0, min(job.dt, job.t_final)
        self.accepted = self.attempts = 0

    def done(self) -> bool:
        return self.t >= self.job.t_final

    def advance(self) -> bool:
        job, sw = self.job, self.sw
        size = sw.SWITCHED_CHUNK if sw.switched else ROWS_PER_CALL
        budget = int(min(sw.SWITCHED_CHUNK if sw.switched else ATTEMPTS_PER_CALL, LIMITS["max_steps"] - self.attempts))
        rows = rows_for(job, sw.module, size)
        args = adaptive_args(
            job,
            sw.p,
            self.x,
            rows,
            self.stats,
            t=self.t,
            h=self.h,
            max_steps=budget,
            accepted=self.accepted,
            rcond_min=sw.threshold,
            solve=self.solve,
        )
        status, self.t, self.h, nrow, self.accepted, att, pending = sw.module.integrate_adaptive(*args)
        self.solve.collect(self.stats)
        sw.h = self.h
        if pending >= 0:  # the call's last row: no step of this call started from it
            forces_at(job, sw.module, sw.p, float(rows.t[pending]), rows.x[pending], rows, pending, self.solve)
        self.attempts += att
        self.chunks.add(rows, nrow)
        self.bar.update(self.t)
        if self.chunks.count >= LIMITS["max_rows"] and not self.done():
            self.status, self.stop = STATUS_FAILED, "max_rows"
            return False
        if status == STATUS_BUDGET:
            status = STATUS_OK
            if self.attempts >= LIMITS["max_steps"]:
                self.status, self.stop = STATUS_FAILED, "max_steps"
                return False
        return self.settle(status, self.t, self.chunks.count)

    def output(self) -> LoopOutput:
        _keep_last(self.job, self.chunks, self.t, self.x, self.solve)
        out = self.chunks.rows()
        evals = self.attempts * self.job.method.stages  # type: ignore[union-attr]
        return self.loop_output(out, self.chunks.count, self.accepted, evals, self.t)


def _keep_last(job: Job, chunks: _Chunks, t: float, x: np.ndarray, solve: SolveState) -> None:
    """Keep the last good state as a row even when thinning (``every``) skipped it."""
    if chunks.last_t() < t - 1e-12 * max(1.0, t):
        rows = rows_for(job, job.module, 1)
        rows.t[0], rows.x[0] = t, x
        job.module.diagnostics_rows(rows.t, rows.x, job.p, rows.E, rows.V)
        if job.forces:
            forces_at(job, job.module, job.p, t, x, rows, 0, solve)
        chunks.add(rows, 1)
