"""Calls into the compiled loops: their arguments built from a :class:`~nmkane_core.integrate.job.Job`
in one place, the output buffers, and the priming that compiles a loop before a run's clock starts.

Every call of a compiled loop — the drivers' real ones and :func:`prepare`'s empty ones —
goes through :func:`fixed_args` or :func:`adaptive_args`, so the argument types are always
those of a real run (numba compiles one copy per type signature) and every setting (the
adaptive loop's minimum step included) is the run's own.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ..kernel import precompile
from ..kernel.constants import STATS_E0, STATS_RCOND_J2, STATS_RCOND_T, STATS_VIOL
from ..kernel.interface import AdaptiveArgs, FixedArgs
from .job import Job
from .methods import ScipyMethod, Tableau

__all__ = ["HMIN_REL", "Rows", "Stopper", "adaptive_args", "fixed_args", "initial_stats", "prepare"]

HMIN_REL = 1e-13  # adaptive runs fail below a step of HMIN_REL · max(1, t_final)


class Rows:
    """Output buffers of one loop call: times, states, energies and violations."""

    def __init__(self, size: int, n2: int, nv: int):
        self.t = np.empty(size)
        self.x = np.empty((size, n2))
        self.E = np.empty(size)
        self.V = np.empty((size, nv))


class Stopper:
    """Why a run should stop between chunks of compiled work: cancelled, or past its time limit."""

    def __init__(self, time_limit: float | None, cancel: Callable[[], bool] | None):
        self.start = time.perf_counter()
        self.time_limit = time_limit
        self.cancel = cancel

    def reason(self) -> str | None:
        if self.cancel is not None and self.cancel():
            return "cancelled"
        if self.time_limit is not None and time.perf_counter() - self.start > self.time_limit:
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
) -> FixedArgs:
    """``integrate_fixed``'s arguments: steps k0 … k1−1 of the job's fixed-step run."""
    tab = job.method
    assert isinstance(tab, Tableau)
    return FixedArgs(
        x=x,
        t0=0.0,
        dt=job.dt,
        t_final=job.t_final,
        k0=k0,
        k1=k1,
        nsteps=fixed_steps(job),
        every=job.every,
        p=p,
        G=job.G,
        G1=job.G1,
        G2=job.G2,
        TA=tab.A,
        TB=tab.b,
        TC=tab.c,
        rcond_min=rcond_min,
        proj=job.proj,
        out_t=rows.t,
        out_x=rows.x,
        out_E=rows.E,
        out_V=rows.V,
        row=row,
        stats=stats,
    )


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
) -> AdaptiveArgs:
    """``integrate_adaptive``'s arguments: from ``t`` with first step ``h``, at most ``max_steps``
    attempts and as many rows as ``rows`` holds."""
    tab = job.method
    assert isinstance(tab, Tableau) and tab.E is not None and tab.error_order is not None
    return AdaptiveArgs(
        x=x,
        t=t,
        t_final=job.t_final,
        h=h,
        rtol=job.rtol,
        atol=job.atol,
        hmin=HMIN_REL * max(1.0, job.t_final),
        hmax=job.t_final,
        max_steps=max_steps,
        every=job.every,
        accepted=accepted,
        p=p,
        G=job.G,
        G1=job.G1,
        G2=job.G2,
        TA=tab.A,
        TB=tab.b,
        TE=tab.E,
        TC=tab.c,
        err_exp=1.0 / (tab.error_order + 1),
        rcond_min=rcond_min,
        proj=job.proj,
        out_t=rows.t,
        out_x=rows.x,
        out_E=rows.E,
        out_V=rows.V,
        stats=stats,
    )


def fixed_steps(job: Job) -> int:
    """Steps of a fixed-step run (the last one shortened to end at t_final)."""
    return max(1, int(np.ceil(job.t_final / job.dt - 1e-9)))


def initial_stats(job: Job, module, p: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The ``stats`` array at the initial state, and its energy and violations."""
    nv = module.NV
    E0, V0 = np.empty(1), np.empty((1, nv))
    module.diagnostics_rows(np.zeros(1), job.x0[None, :], p, E0, V0)
    stats = np.zeros(STATS_VIOL + nv)
    stats[STATS_E0] = E0[0]
    stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = 1.0
    stats[STATS_VIOL:] = np.abs(V0[0])
    return stats, float(E0[0]), V0[0]


def prepare(job: Job) -> None:
    """Load — or, on a model's first use, compile — everything a run of ``job`` calls, so that
    the run itself starts at once (``time_limit`` bounds integration, not compilation): the
    chosen variant's loop and those of every alternative it may switch to."""
    for module, p in [(job.module, job.p), *((a.module, a.p) for a in job.alternatives)]:
        _prime(job, module, p)


def _prime(job: Job, module, p: np.ndarray) -> None:
    """Call the run's compiled loop once with no work (and the helpers a driver calls around
    it: initial diagnostics, the switcher's conditioning check, scipy's right-hand side)."""
    precompile.wait(module)  # a new kernel's loop may be compiling next door
    x = job.x0.copy()
    stats, _, _ = initial_stats(job, module, p)
    if isinstance(job.method, ScipyMethod):
        module.rhs_ws(0.0, x, p, job.G, job.G1, job.G2, np.empty((1, x.size)), 0, module.make_workspace())
        module.diagnostics(0.0, x, p, np.empty(module.NV))
        return
    module.rhs(0.0, x, p, job.G, job.G1, job.G2)  # the switcher's conditioning check
    rows = Rows(1, x.size, module.NV)
    if job.method.adaptive:
        args = adaptive_args(job, p, x, rows, stats, t=0.0, h=job.dt, max_steps=0, accepted=0, rcond_min=0.0)
        module.integrate_adaptive(*args)
    else:
        module.integrate_fixed(*fixed_args(job, p, x, rows, stats, k0=0, k1=0, row=0, rcond_min=0.0))
