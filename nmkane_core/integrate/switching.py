"""Switching between equivalent constraint models near singular configurations (:class:`Switcher`)."""

from __future__ import annotations

import numpy as np

from ..kernel.constants import STATS_VIOL
from ..kernel.interface import CompiledModel
from .calls import conditioning
from .job import Alternative, Job

__all__ = ["Switcher"]


class Switcher:
    """Switching between equivalent constraint models near singular configurations.

    A system may declare, for a variant, equivalent variants (the same motion on the
    constraint manifold, e.g. the nonlinear and linear constraint models of the paper's Example 1); the job lists
    them as its alternatives.  When J2 or T of the chosen model gets a reciprocal-condition
    estimate at or below ``rcond_switch``, the run continues with the first alternative that
    is well-conditioned there, and returns to the chosen model once its estimate is above
    ``SWITCH_BACK × rcond_switch`` again (hysteresis).  Without a cure, the run goes on with
    the chosen model until ``rcond_min`` and then stops as ``singular``.
    """

    SWITCH_BACK = 10.0
    SWITCHED_CHUNK = 25  # steps per call while switched, to return promptly

    def __init__(self, job: Job):
        self.job = job
        self.h = job.dt  # the size of a conditioning check's trial step (the driver keeps it current)
        self.home = Alternative(job.variant, job.module, job.p)
        self.cur = self.home
        self.no_cure = False
        self.switches: list[dict] = []
        self.unknown_multipliers: list[tuple[float, float]] = []  # (from t, to t) of switched rows
        self.segments: list[tuple[int, int]] = []  # output rows computed with another model
        self.seg_start = 0

    @property
    def module(self) -> CompiledModel:
        """The kernel module of the model running now."""
        return self.cur.module

    @property
    def p(self) -> np.ndarray:
        """The parameter vector of the model running now."""
        return self.cur.p

    @property
    def switched(self) -> bool:
        return self.cur is not self.home

    @property
    def threshold(self) -> float:
        job = self.job
        if job.alternatives and not self.switched and not self.no_cure:
            return max(job.rcond_switch, job.rcond_min)
        return job.rcond_min

    def _rcond(self, model: Alternative, t, x) -> float:
        """The model's condition over a trial step from (t, x) (its kernel was loaded with the job)."""
        return conditioning(self.job, model.module, model.p, t, x, self.h)

    def leave(self, t, x, row) -> bool:
        """The chosen model is ill-conditioned at (t, x): switch if an equivalent one is not.

        True when the run should retry from (t, x): with another model, or — the first time
        no equivalent model is better — with the chosen one down to ``rcond_min``.  False
        when nothing is left to try: the run stops as singular (each call either changes
        the model or the threshold, or returns False, so a retry cannot loop)."""
        if self.switched or not self.job.alternatives or self.no_cure:
            return False
        rc_home = self._rcond(self.home, t, x)
        for alt in self.job.alternatives:
            if self._rcond(alt, t, x) > self.job.rcond_switch:
                self.switches.append({"t": float(t), "from": self.home.name, "to": alt.name, "rcond": float(rc_home)})
                self.cur, self.seg_start = alt, row
                return True
        self.no_cure = True
        return True

    def maybe_return(self, t, x, row) -> bool:
        if not self.switched:
            return False
        rc_home = self._rcond(self.home, t, x)
        if rc_home > self.SWITCH_BACK * self.job.rcond_switch:
            self.switches.append({"t": float(t), "from": self.cur.name, "to": self.home.name, "rcond": float(rc_home)})
            self.segments.append((self.seg_start, row))
            self.cur = self.home
            return True
        return False

    def finish(self, row, rows, stats) -> None:
        """Report the chosen model's constraint values on rows computed with another (``rows``:
        the driver's output, with ``t, x, E, V, F, L``).  The constraint forces F_c of those rows
        are the other model's — the same physical forces —, but its multipliers belong to
        other equations: the chosen model's are set to 0 there, and :attr:`unknown_multipliers`
        says when."""
        if self.switched:
            self.segments.append((self.seg_start, row))
        for a, b in self.segments:
            if b > a:
                self.home.module.diagnostics_rows(rows.t[a:b], rows.x[a:b], self.home.p, rows.E[a:b], rows.V[a:b])
                seg = np.abs(rows.V[a:b])
                stats[STATS_VIOL:] = np.maximum(stats[STATS_VIOL:], np.where(np.isfinite(seg), seg, 0.0).max(axis=0))
                first = max(a - 1, 0)  # that row's forces came with the other model's first step
                if rows.L.shape[0]:
                    rows.L[first:b] = 0.0
                    self.unknown_multipliers.append((float(rows.t[first]), float(rows.t[b - 1])))
