"""scipy's solvers (``rk45``, ``dop853``, ``radau``) stepped one step at a time on the compiled
right-hand side, keeping every accepted state up to the last good one.

The right-hand side raises on a singular J2, T or kinematics' C (estimates at rcond_min) and on a
non-finite value, which ends the run with the matching status (scipy's own error control shrinks
the steps near a singular chart: the loops' step check of the kinematics is not made here); the
driver checks the time limit and cancellation every :data:`STEPS_PER_CHECK` steps.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import SingularMatrix
from ..kernel.constants import (
    STATS_E0,
    STATS_FINAL_DRIFT,
    STATS_MAX_DRIFT,
    STATS_RCOND_C,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_VIOL,
    STATUS_C_SINGULAR,
    STATUS_DIVERGED,
    STATUS_DRIFTED,
    STATUS_FAILED,
    STATUS_J2_SINGULAR,
    STATUS_OK,
    STATUS_T_SINGULAR,
)
from ..schema import LIMITS
from ..symbolic.robust import CONSISTENCY_TOL, RANK_TOL, RCOND_ROBUST
from .calls import SolveState, Stopper
from .driver import Driver
from .job import Job, LoopOutput
from .methods import ScipyMethod

__all__ = ["STEPS_PER_CHECK", "ScipyDriver"]

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
        self.rcmin = [1.0, 1.0, 1.0]  # J2, T, the kinematics' C
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
        rc0, rc1, rc2 = w[mod.ORC], w[mod.ORC + 1], w[mod.ORC + 2]
        if not (np.all(np.isfinite(w[: mod.ORC])) and np.all(np.isfinite(self.K[0]))):
            # the model's expressions are not defined here (√ of a negative number, a zero denominator):
            # the run ends "diverged" at the last accepted step.  (Returning NaN would let an explicit
            # solver reject and shrink the step, but it can then creep on along the edge of the domain
            # with ever smaller steps, off the constraint; radau's LU would raise.)
            raise _NonFinite(t)
        self.rcmin = [min(self.rcmin[0], rc0), min(self.rcmin[1], rc1), min(self.rcmin[2], rc2)]
        for name, rc in (("J2", rc0), ("T", rc1), ("C", rc2)):
            if rc <= job.rcond_min:
                raise SingularMatrix(name, rc, t)
        return self.K[0].copy()


class ScipyDriver(Driver):
    """scipy's solver stepped :data:`STEPS_PER_CHECK` steps a chunk, each accepted step's
    diagnostics into the running maxima, every ``every``-th state kept."""

    def __init__(self, job: Job, bar, stopper: Stopper):
        assert isinstance(job.method, ScipyMethod)
        super().__init__(job, bar, stopper)
        self.fun = _RightHandSide(job, self.stats)
        self.ts, self.xs = [0.0], [job.x0.copy()]
        self.count = 0  # accepted steps, kept when the solver raises
        self.fail_msg: str | None = None
        self.viol = np.empty(job.module.NV)
        self.solver = None

    def done(self) -> bool:
        return self.solver is not None and self.solver.status == "finished"

    def advance(self) -> bool:
        import scipy.integrate as si

        job = self.job
        try:
            if self.solver is None:  # its first right-hand side may raise: inside the try
                method = job.method
                assert isinstance(method, ScipyMethod)
                self.solver = getattr(si, method.solver)(
                    self.fun, 0.0, job.x0.copy(), job.t_final, rtol=job.rtol, atol=job.atol,
                    first_step=min(job.dt, job.t_final),
                )  # fmt: skip
            self.status, self.stop, self.fail_msg = self._steps(self.solver)
        except SingularMatrix as e:
            self.status = {"J2": STATUS_J2_SINGULAR, "T": STATUS_T_SINGULAR, "C": STATUS_C_SINGULAR}[e.matrix]
        except _NonFinite:
            self.status = STATUS_DIVERGED
        except _Stopped as e:
            self.status = e.code
        except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:  # raised inside scipy's solver
            self.status = STATUS_FAILED
            self.fail_msg = f"{job.method.name} failed after t = {self.ts[-1]:.6g} s: {e}"
        if self.solver is not None:
            self.bar.update(self.solver.t)
        return self.status == STATUS_OK and self.stop is None

    def _steps(self, solver) -> tuple[int, str | None, str | None]:
        """Up to :data:`STEPS_PER_CHECK` steps, recording rows, running maxima and the count of
        accepted steps in place.  Returns (status, stop, failure message)."""
        job, stats, viol = self.job, self.stats, self.viol
        for _ in range(STEPS_PER_CHECK):
            if solver.status != "running":
                break
            msg = solver.step()
            if solver.status == "failed":
                return STATUS_FAILED, None, msg
            y = solver.y
            if not np.all(np.isfinite(y)):
                return STATUS_DIVERGED, None, None
            self.count += 1
            E = job.module.diagnostics(solver.t, y, job.p, viol)
            if not (math.isfinite(E) and np.all(np.isfinite(viol))):
                return STATUS_DIVERGED, None, None
            stats[STATS_MAX_DRIFT] = max(stats[STATS_MAX_DRIFT], abs(E - stats[STATS_E0]))
            stats[STATS_FINAL_DRIFT] = E - stats[STATS_E0]
            stats[STATS_VIOL:] = np.maximum(stats[STATS_VIOL:], np.abs(viol))
            if abs(E - stats[STATS_E0]) > job.drift_limit or np.any(np.abs(viol) > job.violation_limit):
                return STATUS_DRIFTED, None, None  # past the run's bounds (csrc/loops.c past_bounds)
            if self.count % job.every == 0 or solver.status == "finished":
                self.ts.append(solver.t)
                self.xs.append(y.copy())
                if len(self.ts) >= LIMITS["max_rows"] and solver.status == "running":
                    return STATUS_FAILED, "max_rows", None
            if self.count >= LIMITS["max_steps"]:
                return STATUS_FAILED, "max_steps", None
        return STATUS_OK, None, None

    def output(self) -> LoopOutput:
        job, stats = self.job, self.stats
        stats[STATS_RCOND_J2], stats[STATS_RCOND_T], stats[STATS_RCOND_C] = self.fun.rcmin
        t_arr, x_arr = np.array(self.ts), np.array(self.xs)
        E_arr, V_arr = np.empty(len(self.ts)), np.empty((len(self.ts), job.module.NV))
        job.module.diagnostics_rows(t_arr, x_arr, job.p, E_arr, V_arr)
        rows = len(self.ts) if job.forces else 0
        n, m = (job.module.N, job.module.M) if job.forces else (0, 0)
        F_arr, L_arr = np.zeros((rows, n)), np.zeros((rows, m))
        if job.forces:  # the solver's steps are not the loops': one right-hand side per output row
            job.module.forces_rows(t_arr, x_arr, job.p, job.G, job.G1, job.G2, F_arr, L_arr)
        return LoopOutput(
            status=self.status,
            stop=self.stop,
            t=t_arr,
            x=x_arr,
            E=E_arr,
            V=V_arr,
            F=F_arr,
            L=L_arr,
            stats=stats,
            steps=self.count,
            evals=self.solver.nfev if self.solver is not None else 0,
            t_end=float(t_arr[-1]),
            fail_msg=self.fail_msg,
            solve_log=self.fun.solve.records,
            solve_log_dropped=self.fun.solve.dropped,
        )
