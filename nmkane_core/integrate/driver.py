"""The outer loop every driver shares (:class:`Driver`), and what the two compiled loops' drivers
share besides (:class:`CompiledDriver`).

A driver works in chunks — a call of a compiled loop, or a number of scipy's steps — until the
run reaches ``t_final``, fails, or is stopped.  Between chunks: the progress bar, the time limit
and cancellation, and (compiled loops) a switch of model near a singular configuration.  Each
kind writes only what differs: how a chunk is made (:meth:`Driver.advance`) and how the rows
become the run's output (:meth:`Driver.output`).  :data:`nmkane_core.integrate.drivers.DRIVERS`
picks one by the method's kind.
"""

from __future__ import annotations

from ..kernel.constants import STATUS_J2_SINGULAR, STATUS_OK, STATUS_T_SINGULAR
from .calls import SolveState, Stopper, initial_stats
from .job import Job, LoopOutput
from .switching import Switcher

__all__ = ["CompiledDriver", "Driver"]


class Driver:
    """One run of ``job``: :meth:`run` calls :meth:`advance` until :meth:`done`, a failure or a
    stop, then returns :meth:`output`.  ``status`` and ``stop`` say how it ended."""

    def __init__(self, job: Job, bar, stopper: Stopper):
        self.job, self.bar, self.stopper = job, bar, stopper
        self.stats, self.E0, self.V0 = initial_stats(job, job.module, job.p)
        self.status: int = STATUS_OK
        self.stop: str | None = None

    def done(self) -> bool:
        """Whether the run has reached ``t_final``."""
        raise NotImplementedError

    def advance(self) -> bool:
        """One chunk of work; False when the run ends here (``status``, ``stop`` say why)."""
        raise NotImplementedError

    def output(self) -> LoopOutput:
        """The run's rows and how it ended."""
        raise NotImplementedError

    def run(self) -> LoopOutput:
        while not self.done():
            if not self.advance():
                break
            self.stop = self.stopper.reason()
            if self.stop and not self.done():
                break
            self.stop = None
        return self.output()


class CompiledDriver(Driver):
    """A driver of a compiled loop: the partition and the solve's records (:class:`SolveState`)
    and the switcher between equivalent models (:class:`Switcher`)."""

    def __init__(self, job: Job, bar, stopper: Stopper):
        super().__init__(job, bar, stopper)
        self.solve = SolveState(job, job.module)
        self.sw = Switcher(job)
        self.x = job.x0.copy()

    def settle(self, status: int, t: float, count: int) -> bool:
        """After a call that ended with ``status`` at ``t`` with ``count`` rows: a model switch
        when the chosen one is singular there (True: go on with it), a return to the chosen model
        once it is well-conditioned again; False when the run ends with ``status``."""
        if status in (STATUS_J2_SINGULAR, STATUS_T_SINGULAR) and self.sw.leave(t, self.x, count):
            self.status = STATUS_OK
            return True
        self.status = status
        if status != STATUS_OK:
            return False
        self.sw.maybe_return(t, self.x, count)
        return True

    def loop_output(self, rows, count: int, steps: int, evals: int, t_end: float) -> LoopOutput:
        """The output of ``count`` rows in ``rows``, the switcher's records filled in."""
        self.sw.finish(count, rows, self.stats)
        return LoopOutput(
            status=self.status,
            stop=self.stop,
            t=rows.t[:count],
            x=rows.x[:count],
            E=rows.E[:count],
            V=rows.V[:count],
            F=rows.F[:count],
            L=rows.L[:count, : self.job.module.M],
            stats=self.stats,
            steps=steps,
            evals=evals,
            t_end=t_end,
            switches=self.sw.switches,
            unknown_multipliers=self.sw.unknown_multipliers,
            solve_log=self.solve.records,
            solve_log_dropped=self.solve.dropped,
        )
