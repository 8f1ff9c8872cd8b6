"""The loop drivers: a :class:`~nmkane_core.integrate.job.Job` integrated in chunks of compiled work.

One driver class per kind of method — fixed-step tableaux (:mod:`.fixed`), embedded tableaux
with step control (:mod:`.adaptive`), scipy's solvers (:mod:`.scipy_adapter`) — each a
:class:`~nmkane_core.integrate.driver.Driver` (the outer loop, written once) returning a
:class:`~nmkane_core.integrate.job.LoopOutput` that keeps everything computed up to the last
good step.  Every kernel a job may use is loaded with the job (:meth:`nmkane_core.run.plan.Plan.job`),
before its clock starts.
"""

from __future__ import annotations

from collections.abc import Callable

from .adaptive import ATTEMPTS_PER_CALL, AdaptiveDriver
from .adaptive import ROWS_PER_CALL as ROWS_PER_CALL_ADAPTIVE
from .calls import Stopper
from .driver import Driver
from .fixed import FIRST_CHUNK, FixedDriver
from .job import Job, LoopOutput
from .methods import MethodKind
from .scipy_adapter import STEPS_PER_CHECK, ScipyDriver

__all__ = [
    "ADAPTIVE_ATTEMPTS_PER_CALL",
    "ADAPTIVE_ROWS_PER_CALL",
    "DRIVERS",
    "FIXED_FIRST_CHUNK",
    "ROWS_PER_CHUNK",
    "SCIPY_STEPS_PER_CHECK",
    "LOOP_OF_KIND",
    "integrate",
]

#: how much one chunk of compiled work can add (the service bounds a run's output with these)
ADAPTIVE_ROWS_PER_CALL = ROWS_PER_CALL_ADAPTIVE
ADAPTIVE_ATTEMPTS_PER_CALL = ATTEMPTS_PER_CALL
SCIPY_STEPS_PER_CHECK = STEPS_PER_CHECK
FIXED_FIRST_CHUNK = FIRST_CHUNK


#: the driver of each kind of method (``method.kind``)
DRIVERS: dict[MethodKind, type[Driver]] = {"fixed": FixedDriver, "adaptive": AdaptiveDriver, "scipy": ScipyDriver}
#: the compiled loop each kind calls (None: scipy's solver calls the right-hand side)
LOOP_OF_KIND: dict[MethodKind, str | None] = {
    "fixed": "integrate_fixed",
    "adaptive": "integrate_adaptive",
    "scipy": None,
}
#: the most output rows one chunk of a driver's work adds, given ``every`` (None: a fixed-step
#: run's rows are known before it starts, ``ceil(t_final/dt/every)``)
ROWS_PER_CHUNK: dict[MethodKind, Callable[[int], int] | None] = {
    "fixed": None,
    "adaptive": lambda every: ROWS_PER_CALL_ADAPTIVE,
    "scipy": lambda every: max(1, -(-STEPS_PER_CHECK // every)),
}


def integrate(job: Job, bar, time_limit: float | None = None, cancel: Callable[[], bool] | None = None) -> LoopOutput:
    """Integrate ``job`` with the driver of its method's kind; ``bar.update(t)`` hears the
    progress, ``time_limit`` (s of integration) and ``cancel()`` (polled between chunks) stop it
    early."""
    return DRIVERS[job.method.kind](job, bar, Stopper(time_limit, cancel)).run()
