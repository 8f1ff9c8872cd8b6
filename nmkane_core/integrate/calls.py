"""Calls into the compiled loops: their arguments built from a :class:`~nmkane_core.integrate.job.Job`
in one place, and the output buffers.

Every call of a compiled loop goes through :func:`fixed_args` or :func:`adaptive_args`, so every
setting (the adaptive loop's minimum step included) is the run's own.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from ..kernel.constants import (
    LOG_HEAD,
    STATS_E0,
    STATS_MIN_PIVOT,
    STATS_MIN_RANK,
    STATS_RCOND_C,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_SOLVE_LOG,
    STATS_VIOL,
)
from ..kernel.interface import AdaptiveArgs, CompiledModel, FixedArgs
from ..symbolic.robust import CONSISTENCY_TOL, RANK_TOL, RCOND_ROBUST
from .job import Job
from .methods import Tableau

__all__ = [
    "HMIN_REL",
    "Rows",
    "SolveState",
    "forces_at",
    "rows_for",
    "Stopper",
    "adaptive_args",
    "conditioning",
    "fixed_args",
    "initial_stats",
]

HMIN_REL = 1e-13  # adaptive runs fail below a step of HMIN_REL · max(1, t_final)


class Rows:
    """Output buffers of one loop call: times, states, energies, violations and, when they are
    wanted, constraint forces and multipliers (else arrays of no rows: the loops skip them)."""

    def __init__(self, size: int, n2: int, nv: int, forces: tuple[int, int] | None = None):
        self.t = np.empty(size)
        self.x = np.empty((size, n2))
        self.E = np.empty(size)
        self.V = np.empty((size, nv))
        n, m = forces if forces is not None else (0, 0)
        self.F = np.zeros((size if forces else 0, n))
        self.L = np.zeros((size if forces else 0, m))


def rows_for(job: Job, module: CompiledModel, size: int) -> Rows:
    """Output buffers of ``size`` rows for ``module``'s loop (forces when the job wants them;
    room for the multipliers of any model the run may switch to)."""
    m = max([job.module.M, *(a.module.M for a in job.alternatives)])
    return Rows(size, job.x0.size, module.NV, (module.N, m) if job.forces else None)


class SolveState:
    """The rank-robust solve's state over a run's loop calls (kernels generated with it): the
    partition — J's column order [u_I, u_D], then the solve in use (−1: none yet) — that the
    loops advance in place, and the records of its changes the loops write (``solve_log``)."""

    LOG_ROWS = 64  # records one loop call keeps (more are counted)

    def __init__(self, job: Job, module: CompiledModel, rows: int | None = None):
        n = module.N
        self.order = np.empty(n + 1, dtype=np.int64)
        given = job.order if module is job.module and len(job.order) == n else tuple(range(n))
        self.order[:n] = given
        self.order[n] = -1
        self.max_rank = job.max_rank if job.max_rank >= 0 and module is job.module else int(module.MAX_RANK_DEFAULT)
        self.log = np.zeros((self.LOG_ROWS if rows is None else rows, LOG_HEAD + max(n, module.M)))
        self.records: list[np.ndarray] = []
        self.dropped = 0

    def trial(self) -> SolveState:
        """A copy for a trial step (nothing it records or changes reaches the run)."""
        other = object.__new__(SolveState)
        other.order, other.max_rank = self.order.copy(), self.max_rank
        other.log, other.records, other.dropped = np.zeros((0, self.log.shape[1])), [], 0
        return other

    def collect(self, stats: np.ndarray) -> None:
        """The records of the last loop call, kept; the loops' count reset."""
        k = int(stats[STATS_SOLVE_LOG])
        kept = min(k, self.log.shape[0])
        self.records.extend(row.copy() for row in self.log[:kept])
        self.dropped += k - kept
        stats[STATS_SOLVE_LOG] = 0.0


def solve_state(job: Job, module: CompiledModel, state: SolveState | None) -> SolveState:
    """``state`` when it belongs to ``module``, else a fresh one for a trial step of it."""
    if state is not None and state.order.size == module.N + 1:
        return state
    return SolveState(job, module, rows=0)


class Stopper:
    """Why a run should stop between chunks of compiled work: cancelled, or past its time limit
    (which bounds integration: every kernel the run may use is loaded before it starts)."""

    def __init__(self, time_limit: float | None, cancel: Callable[[], bool] | None):
        self.start = time.perf_counter()
        self.time_limit = time_limit
        self.cancel = cancel

    def reason(self) -> str | None:
        if self.cancel is not None and self.cancel():
            return "cancelled"
        spent = time.perf_counter() - self.start
        if self.time_limit is not None and spent > self.time_limit:
            return "timeout"
        return None


def fixed_args(
    job: Job,
    p: np.ndarray,
    x: np.ndarray,
    rows: Rows,
    stats: np.ndarray,
    *,
    k0: int,
    k1: int,
    row: int,
    rcond_min: float,
    pending: int = -1,
    t0: float = 0.0,
    steps: tuple[float, float, int] | None = None,
    solve: SolveState,
    bounded: bool = True,
) -> FixedArgs:
    """``integrate_fixed``'s arguments: steps k0 … k1−1 of the job's fixed-step run (or, with
    ``steps = (dt, t_final, nsteps)`` from ``t0``, of another grid: a trial step, with
    ``bounded=False``: its statistics start afresh, so the run's drift bounds do not apply)."""
    tab = job.method
    assert isinstance(tab, Tableau)
    dt, t_final, nsteps = steps if steps is not None else (job.dt, job.t_final, fixed_steps(job))
    return FixedArgs(
        t0=t0,
        dt=dt,
        t_final=t_final,
        k0=k0,
        k1=k1,
        nsteps=nsteps,
        row=row,
        **_common_args(job, tab, p, x, rows, stats, rcond_min, pending, solve, bounded),
    )


def _common_args(
    job: Job,
    tab: Tableau,
    p: np.ndarray,
    x: np.ndarray,
    rows: Rows,
    stats: np.ndarray,
    rcond_min,
    pending,
    solve,
    bounded: bool,
) -> dict:
    """The arguments both compiled loops take (:class:`FixedArgs` and :class:`AdaptiveArgs`
    share these fields by name): the run's numbers from the job, the solve's state, the buffers."""
    return {
        "x": x,
        "every": job.every,
        "p": p,
        "G": job.G,
        "G1": job.G1,
        "G2": job.G2,
        "TA": tab.A,
        "TB": tab.b,
        "TC": tab.c,
        "rcond_min": rcond_min,
        "drift_limit": job.drift_limit if bounded else math.inf,
        "violation_limit": job.violation_limit if bounded else math.inf,
        "solve": job.solve,
        "rank_tol": RANK_TOL,
        "max_rank": solve.max_rank,
        "consistency_tol": CONSISTENCY_TOL,
        "rcond_robust": RCOND_ROBUST,
        "order": solve.order,
        "solve_log": solve.log,
        "proj": job.proj,
        "near_proj": job.near_proj,
        "out_t": rows.t,
        "out_x": rows.x,
        "out_E": rows.E,
        "out_V": rows.V,
        "out_F": rows.F,
        "out_L": rows.L,
        "pending": pending,
        "stats": stats,
    }


def adaptive_args(
    job: Job,
    p: np.ndarray,
    x: np.ndarray,
    rows: Rows,
    stats: np.ndarray,
    *,
    t: float,
    h: float,
    max_steps: int,
    accepted: int,
    rcond_min: float,
    pending: int = -1,
    t_final: float | None = None,
    solve: SolveState,
    bounded: bool = True,
) -> AdaptiveArgs:
    """``integrate_adaptive``'s arguments: from ``t`` with first step ``h``, at most ``max_steps``
    attempts and as many rows as ``rows`` holds (``bounded=False``: a trial step, without the
    run's drift bounds)."""
    tab = job.method
    assert isinstance(tab, Tableau) and tab.E is not None and tab.error_order is not None
    return AdaptiveArgs(
        t=t,
        t_final=job.t_final if t_final is None else t_final,
        h=h,
        rtol=job.rtol,
        atol=job.atol,
        hmin=HMIN_REL * max(1.0, job.t_final),
        hmax=job.t_final,
        max_steps=max_steps,
        accepted=accepted,
        TE=tab.E,
        err_exp=1.0 / (tab.error_order + 1),
        **_common_args(job, tab, p, x, rows, stats, rcond_min, pending, solve, bounded),
    )


def fixed_steps(job: Job) -> int:
    """Steps of a fixed-step run (the last one shortened to end at t_final)."""
    return max(1, int(np.ceil(job.t_final / job.dt - 1e-9)))


def initial_stats(job: Job, module: CompiledModel, p: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The ``stats`` array at the initial state, and its energy and violations."""
    nv = module.NV
    E0, V0 = np.empty(1), np.empty((1, nv))
    module.diagnostics_rows(np.zeros(1), job.x0[None, :], p, E0, V0)
    stats = np.zeros(STATS_VIOL + nv)
    stats[STATS_E0] = E0[0]
    stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = stats[STATS_RCOND_C] = 1.0
    stats[STATS_MIN_PIVOT], stats[STATS_MIN_RANK] = 1.0, module.M
    stats[STATS_VIOL:] = np.abs(V0[0])
    return stats, float(E0[0]), V0[0]


def _trial_stats(module: CompiledModel) -> np.ndarray:
    stats = np.zeros(STATS_VIOL + module.NV)
    stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = stats[STATS_RCOND_C] = stats[STATS_MIN_PIVOT] = 1.0
    stats[STATS_MIN_RANK] = module.M
    return stats


def conditioning(
    job: Job, module: CompiledModel, p: np.ndarray, t: float, x: np.ndarray, h: float, solve: SolveState | None = None
) -> float:
    """The smallest reciprocal-condition estimate of J2 and T over one trial step of size ``h``
    from (t, x) with ``module``'s loop (on copies: nothing of the run changes).  The switcher
    asks this of a model before it switches to it or back (no other compiled function needed)."""
    stats = _trial_step(job, module, p, t, x, h, Rows(2, x.size, module.NV), solve, pending=-1)
    return float(min(stats[STATS_RCOND_J2], stats[STATS_RCOND_T]))


def forces_at(
    job: Job,
    module: CompiledModel,
    p: np.ndarray,
    t: float,
    x: np.ndarray,
    rows: Rows,
    row: int,
    solve: SolveState | None = None,
) -> None:
    """The constraint forces of the state (t, x) into ``rows.F[row]``, ``rows.L[row]``: the first
    stage of a trial step of ``module``'s loop (on copies: nothing of the run changes; no other
    compiled function needed).  For a row no step of the run started from: its last."""
    out = rows_for(job, module, 2)
    _trial_step(job, module, p, t, x, job.dt, out, solve, pending=0)
    rows.F[row], rows.L[row] = out.F[0], out.L[0]


def _trial_step(
    job: Job,
    module: CompiledModel,
    p: np.ndarray,
    t: float,
    x: np.ndarray,
    h: float,
    rows: Rows,
    solve: SolveState | None,
    pending: int,
) -> np.ndarray:
    """One step of size ``h`` from (t, x) with ``module``'s loop, on copies (a trial solve state,
    fresh statistics, no drift bounds): its statistics.  ``pending=0``: the forces of the first
    stage into ``rows``' row 0; the step's own row goes to row 1 (fixed steps) or 0 (adaptive)."""
    stats = _trial_stats(module)
    y = x.copy()
    trial = solve_state(job, module, solve).trial()
    if job.method.kind == "adaptive":
        module.integrate_adaptive(
            *adaptive_args(
                job, p, y, rows, stats, t=t, h=h, max_steps=1, accepted=0, rcond_min=0.0, pending=pending,
                t_final=t + h, solve=trial, bounded=False,
            )
        )  # fmt: skip
    else:
        module.integrate_fixed(
            *fixed_args(
                job, p, y, rows, stats, k0=0, k1=1, row=1, rcond_min=0.0, pending=pending, t0=t,
                steps=(h, t + h, 1), solve=trial, bounded=False,
            )
        )  # fmt: skip
    return stats
