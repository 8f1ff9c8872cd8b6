"""scipy's solvers (``rk45``, ``dop853``, ``radau``) stepped one step at a time on the compiled
right-hand side, keeping every accepted state up to the last good one.

The right-hand side raises on a singular J2 or T and on a non-finite value, which ends the
run with the matching status; the driver checks the time limit and cancellation every
:data:`STEPS_PER_CHECK` steps.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SingularMatrix
from ..kernel.constants import (
    STATS_E0,
    STATS_FINAL_DRIFT,
    STATS_MAX_DRIFT,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_VIOL,
    STATUS_DIVERGED,
    STATUS_FAILED,
    STATUS_J2_SINGULAR,
    STATUS_OK,
    STATUS_T_SINGULAR,
)
from ..schema import LIMITS
from ..symbolic.robust import CONSISTENCY_TOL, RANK_TOL, RCOND_ROBUST
from .calls import SolveState, Stopper, initial_stats
from .job import Job, LoopOutput
from .methods import ScipyMethod

__all__ = ["STEPS_PER_CHECK", "run_scipy"]

STEPS_PER_CHECK = 200  # the scipy adapter checks time limit and cancellation this often


class _NonFinite(ArithmeticError):
    """The right-hand side is not finite at a state a scipy solver asked for."""


class _Stopped(ArithmeticError):
    """The rank-robust solve ended the run (a ``STATUS_*`` code: Q singular, inconsistent)."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


class _RightHandSide:
    """f(t, x) for scipy from the compiled kernel, with the smallest condition estimates seen."""

    def __init__(self, job: Job, stats: np.ndarray):
        self.job, self.mod = job, job.module
        self.w = self.mod.make_workspace()
        self.K = np.empty((1, job.x0.size))
        self.rcmin = [1.0, 1.0]
        self.stats = stats
        self.solve = SolveState(job, job.module)
        if self.mod.ROBUST:
            s = self.solve
            self.mod.solve_setup(
                self.w, job.solve, RANK_TOL, s.max_rank, CONSISTENCY_TOL, RCOND_ROBUST, job.rcond_min, s.order, False
            )  # no projection between scipy's steps: the Baumgarte terms stay whole
        self.f = self.mod.rhs_bound(job.p, job.G, job.G1, job.G2, self.K, self.w)

    def __call__(self, t, x):
        job, mod, w = self.job, self.mod, self.w
        self.f(t, x)
        if mod.ROBUST:  # the loops' bookkeeping of the rank-robust solve (kernel/csrc/loops.c)
            code = mod._robust_outcome(t, 0.0, w, self.stats, self.solve.order, self.solve.log, True)
            self.solve.collect(self.stats)
            if code != STATUS_OK:
                raise _NonFinite(t) if code == STATUS_DIVERGED else _Stopped(code)
        rc0, rc1 = w[mod.ORC], w[mod.ORC + 1]
        if not (np.all(np.isfinite(w[: mod.ORC])) and np.all(np.isfinite(self.K[0]))):
            # the model's expressions are not defined here (√ of a negative number, a zero denominator):
            # the run ends "diverged" at the last accepted step.  (Returning NaN would let an explicit
            # solver reject and shrink the step, but it can then creep on along the edge of the domain
            # with ever smaller steps, off the constraint; radau's LU would raise.)
            raise _NonFinite(t)
        self.rcmin[0], self.rcmin[1] = min(self.rcmin[0], rc0), min(self.rcmin[1], rc1)
        if rc0 <= job.rcond_min:
            raise SingularMatrix("J2", rc0, t)
        if rc1 <= job.rcond_min:
            raise SingularMatrix("T", rc1, t)
        return self.K[0].copy()


def run_scipy(job: Job, bar, stopper: Stopper) -> LoopOutput:
    """Integrate ``job`` with its scipy solver; keeps every ``every``-th accepted step."""
    import scipy.integrate as si

    assert isinstance(job.method, ScipyMethod)
    stats, _, _ = initial_stats(job, job.module, job.p)
    fun = _RightHandSide(job, stats)
    ts, xs = [0.0], [job.x0.copy()]
    status, stop, nfev, fail_msg = STATUS_OK, None, 0, None
    count = [0]  # accepted steps, kept when the solver raises
    try:
        solver = getattr(si, job.method.solver)(
            fun, 0.0, job.x0.copy(), job.t_final, rtol=job.rtol, atol=job.atol, first_step=min(job.dt, job.t_final)
        )
        status, stop, fail_msg = _step(job, solver, stats, ts, xs, count, bar, stopper)
        nfev = solver.nfev
    except SingularMatrix as e:
        status = STATUS_J2_SINGULAR if e.matrix == "J2" else STATUS_T_SINGULAR
    except _NonFinite:
        status = STATUS_DIVERGED
    except _Stopped as e:
        status = e.code
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:  # raised inside scipy's solver
        status = STATUS_FAILED
        fail_msg = f"{job.method.name} failed after t = {ts[-1]:.6g} s: {e}"
    stats[STATS_RCOND_J2], stats[STATS_RCOND_T] = fun.rcmin
    t_arr, x_arr = np.array(ts), np.array(xs)
    E_arr, V_arr = np.empty(len(ts)), np.empty((len(ts), job.module.NV))
    job.module.diagnostics_rows(t_arr, x_arr, job.p, E_arr, V_arr)
    n, m = (job.module.N, job.module.M) if job.forces else (0, 0)
    F_arr, L_arr = np.zeros((len(ts) if job.forces else 0, n)), np.zeros((len(ts) if job.forces else 0, m))
    if job.forces:  # the solver's steps are not the loops': one right-hand side per output row
        job.module.forces_rows(t_arr, x_arr, job.p, job.G, job.G1, job.G2, F_arr, L_arr)
    return LoopOutput(
        status=status,
        stop=stop,
        t=t_arr,
        x=x_arr,
        E=E_arr,
        V=V_arr,
        F=F_arr,
        L=L_arr,
        stats=stats,
        steps=count[0],
        evals=nfev,
        t_end=float(t_arr[-1]),
        fail_msg=fail_msg,
        solve_log=fun.solve.records,
        solve_log_dropped=fun.solve.dropped,
    )


def _step(job: Job, solver, stats, ts: list, xs: list, count: list, bar, stopper: Stopper):
    """Step the solver to the end (or a stop), recording rows, running maxima and the count of
    accepted steps (``count[0]``) in place.  Returns (status, stop, failure message)."""
    viol = np.empty(job.module.NV)
    while solver.status == "running":
        msg = solver.step()
        if solver.status == "failed":
            return STATUS_FAILED, None, msg
        y = solver.y
        if not np.all(np.isfinite(y)):
            return STATUS_DIVERGED, None, None
        count[0] += 1
        nstep = count[0]
        E = job.module.diagnostics(solver.t, y, job.p, viol)
        if not (math.isfinite(E) and np.all(np.isfinite(viol))):
            return STATUS_DIVERGED, None, None
        stats[STATS_MAX_DRIFT] = max(stats[STATS_MAX_DRIFT], abs(E - stats[STATS_E0]))
        stats[STATS_FINAL_DRIFT] = E - stats[STATS_E0]
        stats[STATS_VIOL:] = np.maximum(stats[STATS_VIOL:], np.abs(viol))
        if nstep % job.every == 0 or solver.status == "finished":
            ts.append(solver.t)
            xs.append(y.copy())
            if len(ts) >= LIMITS["max_rows"] and solver.status == "running":
                return STATUS_FAILED, "max_rows", None
        if nstep >= LIMITS["max_steps"]:
            return STATUS_FAILED, "max_steps", None
        if nstep % STEPS_PER_CHECK == 0:
            bar.update(solver.t)
            stop = stopper.reason()
            if stop:
                return STATUS_OK, stop, None
    return STATUS_OK, None, None
