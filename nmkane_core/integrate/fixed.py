"""The fixed-step driver: ``integrate_fixed`` called chunk by chunk for a whole run.

Between chunks the driver updates the progress bar, checks the time limit and cancellation,
and lets the :class:`~nmkane_core.integrate.switching.Switcher` change the model near a
singular configuration.  The first chunk is :data:`FIRST_CHUNK` steps; later ones aim at
:data:`CHUNK_SECONDS` of work each.
"""

from __future__ import annotations

import time

import numpy as np

from ..kernel.constants import STATUS_J2_SINGULAR, STATUS_OK, STATUS_T_SINGULAR
from .calls import Rows, SolveState, Stopper, fixed_args, fixed_steps, forces_at, initial_stats, rows_for
from .job import Job, LoopOutput
from .switching import Switcher

__all__ = ["FIRST_CHUNK", "run_fixed"]

FIRST_CHUNK = 2000  # steps of the first fixed-step call; later calls aim at ~50 ms each
CHUNK_SECONDS = 0.05
MIN_CHUNK, MAX_CHUNK = 500, 5_000_000


def run_fixed(job: Job, bar, stopper: Stopper) -> LoopOutput:
    """Integrate ``job`` with its fixed-step tableau; keeps every row up to the last good step."""
    nsteps = fixed_steps(job)
    every = job.every
    rows = rows_for(job, job.module, nsteps // every + (1 if nsteps % every else 0) + 2)
    stats, E0, V0 = initial_stats(job, job.module, job.p)
    rows.t[0], rows.x[0], rows.E[0], rows.V[0] = 0.0, job.x0, E0, V0
    x = job.x0.copy()
    row, k, status, stop = 1, 0, STATUS_OK, None
    pending = 0 if job.forces else -1  # the initial row's forces come with the first step
    chunk = FIRST_CHUNK
    sw = Switcher(job)
    solve = SolveState(job, job.module)
    while k < nsteps:
        t_call = time.perf_counter()
        k_end = min(nsteps, k + (sw.SWITCHED_CHUNK if sw.switched else chunk))
        args = fixed_args(
            job, sw.p, x, rows, stats, k0=k, k1=k_end, row=row, rcond_min=sw.threshold, pending=pending, solve=solve
        )
        status, k, row, pending = sw.module.integrate_fixed(*args)
        solve.collect(stats)
        if not sw.switched:
            chunk = _next_chunk(chunk, time.perf_counter() - t_call)
        bar.update(min(k * job.dt, job.t_final))
        if status in (STATUS_J2_SINGULAR, STATUS_T_SINGULAR) and sw.leave(k * job.dt, x, row):
            status = STATUS_OK
            continue
        if status != STATUS_OK:
            break
        sw.maybe_return(k * job.dt, x, row)
        stop = stopper.reason()
        if stop and k < nsteps:
            break
    t_last = job.t_final if k >= nsteps and status == STATUS_OK else k * job.dt
    row, pending = _keep_last(job, rows, row, t_last, x, pending)
    if pending >= 0:  # the last row: no step started from it
        forces_at(job, job.module, job.p, float(rows.t[pending]), rows.x[pending], rows, pending, solve)
    sw.finish(row, rows, stats)
    return LoopOutput(
        status=status,
        stop=stop,
        t=rows.t[:row],
        x=rows.x[:row],
        E=rows.E[:row],
        V=rows.V[:row],
        F=rows.F[:row],
        L=rows.L[:row, : job.module.M],
        stats=stats,
        steps=k,
        evals=k * job.method.stages,  # type: ignore[union-attr]
        t_end=t_last,
        switches=sw.switches,
        unknown_multipliers=sw.unknown_multipliers,
        solve_log=solve.records,
        solve_log_dropped=solve.dropped,
    )


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
