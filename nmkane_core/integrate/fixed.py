"""The fixed-step driver: ``integrate_fixed`` called chunk by chunk for a whole run.

Between chunks the driver updates the progress bar, checks the time limit and cancellation,
and lets the :class:`~nmkane_core.integrate.switching.Switcher` change the model near a
singular configuration.  The first chunk is :data:`FIRST_CHUNK` steps; later ones aim at
:data:`CHUNK_SECONDS` of work each.
"""

from __future__ import annotations

import time

import numpy as np

from ..kernel.constants import STATUS_OK
from .calls import Rows, Stopper, fixed_args, fixed_steps, forces_at, rows_for
from .driver import CompiledDriver
from .job import Job, LoopOutput

__all__ = ["FIRST_CHUNK", "FixedDriver"]

FIRST_CHUNK = 2000  # steps of the first fixed-step call; later calls aim at ~50 ms each
CHUNK_SECONDS = 0.05
MIN_CHUNK, MAX_CHUNK = 500, 5_000_000


class FixedDriver(CompiledDriver):
    """``integrate_fixed`` chunk by chunk: every row is known ahead (``ceil(t_final/dt/every)``),
    so the rows are one buffer; the chunks grow toward :data:`CHUNK_SECONDS` of work."""

    def __init__(self, job: Job, bar, stopper: Stopper):
        super().__init__(job, bar, stopper)
        self.nsteps = nsteps = fixed_steps(job)
        self.rows = rows_for(job, job.module, nsteps // job.every + (1 if nsteps % job.every else 0) + 2)
        self.rows.t[0], self.rows.x[0], self.rows.E[0], self.rows.V[0] = 0.0, job.x0, self.E0, self.V0
        self.row, self.k = 1, 0
        self.pending = 0 if job.forces else -1  # the initial row's forces come with the first step
        self.chunk = FIRST_CHUNK

    def done(self) -> bool:
        return self.k >= self.nsteps

    def advance(self) -> bool:
        job, sw = self.job, self.sw
        t_call = time.perf_counter()
        k_end = min(self.nsteps, self.k + (sw.SWITCHED_CHUNK if sw.switched else self.chunk))
        args = fixed_args(
            job,
            sw.p,
            self.x,
            self.rows,
            self.stats,
            k0=self.k,
            k1=k_end,
            row=self.row,
            rcond_min=sw.threshold,
            pending=self.pending,
            solve=self.solve,
        )
        status, self.k, self.row, self.pending = sw.module.integrate_fixed(*args)
        self.solve.collect(self.stats)
        if not sw.switched:
            self.chunk = _next_chunk(self.chunk, time.perf_counter() - t_call)
        self.bar.update(min(self.k * job.dt, job.t_final))
        return self.settle(status, self.k * job.dt, self.row)

    def output(self) -> LoopOutput:
        job = self.job
        t_last = job.t_final if self.done() and self.status == STATUS_OK else self.k * job.dt
        self.row, self.pending = _keep_last(job, self.rows, self.row, t_last, self.x, self.pending)
        if self.pending >= 0:  # the last row: no step started from it
            p = self.pending
            forces_at(job, job.module, job.p, float(self.rows.t[p]), self.rows.x[p], self.rows, p, self.solve)
        evals = self.k * job.method.stages  # type: ignore[union-attr]
        return self.loop_output(self.rows, self.row, self.k, evals, t_last)


def _next_chunk(chunk: int, elapsed: float) -> int:
    """The next chunk's steps: aim at CHUNK_SECONDS, growing at most fourfold."""
    return int(min(max(chunk * min(4.0, CHUNK_SECONDS / max(elapsed, 1e-6)), MIN_CHUNK), MAX_CHUNK))


def _keep_last(job: Job, rows: Rows, row: int, t_last: float, x: np.ndarray, pending: int) -> tuple[int, int]:
    """Keep the last good state as a row even when thinning (``every``) skipped it; returns the
    next free row and the row still waiting for its forces (the kept one, when added)."""
    if row == 0 or rows.t[row - 1] < t_last - 1e-12 * max(1.0, t_last):
        rows.t[row], rows.x[row] = t_last, x
        job.module.diagnostics_rows(
            rows.t[row : row + 1], rows.x[row : row + 1], job.p, rows.E[row : row + 1], rows.V[row : row + 1]
        )
        pending = row if job.forces else -1
        row += 1
    return row, pending
