"""The loop drivers: a :class:`~nmkane_core.integrate.job.Job` integrated in chunks of compiled work.

One driver per kind of method — fixed-step tableaux (:mod:`.fixed`), embedded tableaux with
step control (:mod:`.adaptive`), scipy's solvers (:mod:`.scipy_adapter`) — each returning a
:class:`~nmkane_core.integrate.job.LoopOutput` that keeps everything computed up to the last
good step.  :func:`~nmkane_core.integrate.calls.prepare` loads (or compiles) what a job
needs before its clock starts.
"""

from __future__ import annotations

from collections.abc import Callable

from .adaptive import ATTEMPTS_PER_CALL, ROWS_PER_CALL, run_adaptive
from .calls import Stopper, prepare
from .fixed import FIRST_CHUNK, run_fixed
from .job import Job, LoopOutput
from .methods import ScipyMethod
from .scipy_adapter import STEPS_PER_CHECK, run_scipy

__all__ = [
    "ADAPTIVE_ATTEMPTS_PER_CALL",
    "ADAPTIVE_ROWS_PER_CALL",
    "FIXED_FIRST_CHUNK",
    "SCIPY_STEPS_PER_CHECK",
    "integrate",
    "prepare",
]

#: how much one chunk of compiled work can add (the service bounds a run's output with these)
ADAPTIVE_ROWS_PER_CALL = ROWS_PER_CALL
ADAPTIVE_ATTEMPTS_PER_CALL = ATTEMPTS_PER_CALL
SCIPY_STEPS_PER_CHECK = STEPS_PER_CHECK
FIXED_FIRST_CHUNK = FIRST_CHUNK


def integrate(job: Job, bar, time_limit: float | None = None, cancel: Callable[[], bool] | None = None) -> LoopOutput:
    """Integrate ``job`` with the driver of its method; ``bar.update(t)`` hears the progress,
    ``time_limit`` (s of integration) and ``cancel()`` (polled between chunks) stop it early."""
    stopper = Stopper(time_limit, cancel)
    if isinstance(job.method, ScipyMethod):
        return run_scipy(job, bar, stopper)
    if job.method.adaptive:
        return run_adaptive(job, bar, stopper)
    return run_fixed(job, bar, stopper)
