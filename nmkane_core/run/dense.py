"""The state between a run's output rows, to the integrator's accuracy: output at asked times
(``RunSettings.output_times``, like scipy's ``t_eval``) and event crossings located in time.

A state at time t is not interpolated between the rows around it: the run's own method steps
from the row before t (its state, as the loops wrote it) over the run's steps to t, the last
step shortened to end there — for a fixed-step run the same steps as the run's (the same
arithmetic: a time on the grid gives the row's bits), with its projection and gains; for an
adaptive run one step of at most the accepted step's size (``every`` = 1) with the method's
tableau; for scipy's solvers Kutta–Merson steps of 1/16 of the solver's own.  So the
error at t is the integrator's, whatever ``every`` thinned the rows to.  Where the re-integration
cannot go (a singular J2 there, a switched model's rows), the state is interpolated linearly and
a warning says so.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ..integrate.calls import SolveState, fixed_args, rows_for
from ..integrate.job import Job, LoopOutput
from ..integrate.methods import KUTTA_MERSON, Tableau
from ..kernel.constants import STATS_RCOND_C, STATS_RCOND_J2, STATS_RCOND_T, STATS_VIOL, STATUS_OK

__all__ = ["Dense"]


class Dense:
    """States at any times within a finished run's rows (``out``: the driver's output)."""

    def __init__(self, job: Job, out: LoopOutput):
        self.job, self.out = job, out
        method = job.method if isinstance(job.method, Tableau) else KUTTA_MERSON
        self.fixed = job.method.kind == "fixed"
        # a scipy solver's rows are its steps, of its own order (dop853: 8): Kutta–Merson over
        # 1/16 of such a step has 16⁴ less error than over all of it
        self.substeps = 1 if isinstance(job.method, Tableau) else 16
        self.step_job = replace(job, method=method, every=1, alternatives=())
        self.fallbacks = 0  # times given by linear interpolation

    def state(self, t: float) -> np.ndarray:
        """The state at ``t`` (within the rows' span)."""
        out = self.out
        r = int(np.searchsorted(out.t, t, side="right")) - 1
        r = min(max(r, 0), len(out.t) - 1)
        t0, x0 = float(out.t[r]), out.x[r]
        if t <= t0 or r == len(out.t) - 1:
            return x0.copy()
        h = self.job.dt if self.fixed else (float(out.t[r + 1]) - t0) / self.substeps
        y = self._advance(t0, x0, t, h)
        if y is None:
            self.fallbacks += 1
            a = (t - t0) / (float(out.t[r + 1]) - t0)
            return (1.0 - a) * x0 + a * out.x[r + 1]
        return y

    def states(self, times) -> np.ndarray:
        return np.array([self.state(float(t)) for t in times]).reshape(len(times), self.out.x.shape[1])

    def _advance(self, t0: float, x0: np.ndarray, t: float, h: float) -> np.ndarray | None:
        """x0 at t0 stepped to t with steps of h (the last shortened), or None where it fails."""
        job = self.step_job
        n = max(1, math.ceil((t - t0) / h - 1e-9))
        y = x0.copy()
        rows = rows_for(job, job.module, 2)
        stats = np.zeros(STATS_VIOL + job.module.NV)
        stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = stats[STATS_RCOND_C] = 1.0
        args = fixed_args(
            replace(job, every=n), job.p, y, rows, stats, k0=0, k1=n, row=0, rcond_min=job.rcond_min,
            t0=t0, steps=(h, t, n), solve=SolveState(job, job.module), bounded=False,
        )  # fmt: skip
        status = job.module.integrate_fixed(*args)[0]
        return y if status == STATUS_OK and np.all(np.isfinite(y)) else None
