"""Switching between equivalent constraint models near singular configurations (:class:`Switcher`)."""

from __future__ import annotations

import numpy as np

from ..kernel.built import built
from ..kernel.interface import STATS_VIOL
from ..run.plan import Plan

__all__ = ["Switcher"]


class Switcher:
    """Switching between equivalent constraint models near singular configurations.

    A system may declare, for a variant, equivalent variants (the same motion on the
    constraint manifold, e.g. the Appell–Hamel nonlinear and linear models).  When J2 or T
    of the selected model gets a reciprocal-condition estimate at or below
    ``rcond_switch``, the run continues with the first equivalent variant that is
    well-conditioned there, and returns to the selected model once its estimate is above
    ``SWITCH_BACK × rcond_switch`` again (hysteresis).  Without a cure, the run goes on with
    the selected model until ``rcond_min`` and then stops as ``singular``.
    """

    SWITCH_BACK = 10.0
    SWITCHED_CHUNK = 25  # steps per call while switched, to return promptly

    def __init__(self, plan: Plan, home):
        self.plan = plan
        self.home = home
        self.cur = home
        self.cur_name = plan.variant
        self.alts = list(plan.system.equivalents.get(plan.variant, ())) if plan.switching else []
        self.no_cure = False
        self.switches: list[dict] = []
        self.segments: list[tuple[int, int]] = []  # output rows computed with another model
        self.seg_start = 0
        self._p = {id(home): plan.p}  # each variant's parameter vector, bound by name

    @property
    def p(self):
        """The parameter vector of the model running now (variants may order parameters differently)."""
        return self._p[id(self.cur)]

    def _p_of(self, mod, variant: str):
        if id(mod) not in self._p:
            self._p[id(mod)] = built(self.plan.system).param_vector(variant, self.plan.params)
        return self._p[id(mod)]

    @property
    def switched(self) -> bool:
        return self.cur is not self.home

    @property
    def threshold(self) -> float:
        if self.alts and not self.switched and not self.no_cure:
            return max(self.plan.rcond_switch, self.plan.rcond_min)
        return self.plan.rcond_min

    def _rcond(self, mod, t, x, variant: str | None = None):
        p = self._p_of(mod, variant) if variant is not None else self._p[id(mod)]
        _, rc0, rc1 = mod.rhs(t, x, p, self.plan.G, self.plan.G1, self.plan.G2)
        return min(rc0, rc1)

    def leave(self, t, x, row) -> bool:
        """The selected model is ill-conditioned at (t, x): switch if an equivalent one is not.

        True when the run should retry from (t, x): with another model, or — the first time
        no equivalent model is better — with the selected one down to ``rcond_min``.  False
        when nothing is left to try: the run stops as singular (each call either changes
        the model or the threshold, or returns False, so a retry cannot loop)."""
        if self.switched or not self.alts or self.no_cure:
            return False
        rc_home = self._rcond(self.home, t, x)
        for v in self.alts:
            mod = built(self.plan.system).module(v)
            if self._rcond(mod, t, x, v) > self.plan.rcond_switch:
                self.switches.append({"t": float(t), "from": self.plan.variant, "to": v, "rcond": float(rc_home)})
                self.cur, self.cur_name, self.seg_start = mod, v, row
                return True
        self.no_cure = True
        return True

    def maybe_return(self, t, x, row) -> bool:
        if not self.switched:
            return False
        rc_home = self._rcond(self.home, t, x)
        if rc_home > self.SWITCH_BACK * self.plan.rcond_switch:
            self.switches.append(
                {"t": float(t), "from": self.cur_name, "to": self.plan.variant, "rcond": float(rc_home)}
            )
            self.segments.append((self.seg_start, row))
            self.cur, self.cur_name = self.home, self.plan.variant
            return True
        return False

    def finish(self, row, t, x, E, V, stats):
        """Report the selected model's constraint values on rows computed with another."""
        if self.switched:
            self.segments.append((self.seg_start, row))
        for a, b in self.segments:
            if b > a:
                self.home.diagnostics_rows(t[a:b], x[a:b], self.plan.p, E[a:b], V[a:b])
                seg = np.abs(V[a:b])
                stats[STATS_VIOL:] = np.maximum(stats[STATS_VIOL:], np.where(np.isfinite(seg), seg, 0.0).max(axis=0))
