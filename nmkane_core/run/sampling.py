"""A refined adaptive run's states at another run's output times (:mod:`.accuracy`).

The refined run keeps every step (``every`` = 1).  At each asked time t its state is the
Lagrange polynomial through the :data:`POINTS` refined rows nearest t (degree 7), checked
against the polynomial of one degree less: where the two differ by more than the refined run's
own tolerance, atol + rtol·|x|, in any component (the run's steps are long for the
polynomial: an 8th-order method's), the state is instead stepped to from the refined row
before t with an embedded Runge–Kutta pair at the refined run's tolerances (the run's own
tableau, or Kutta–Merson for scipy's solvers), its projection and gains.  Where even that
fails (a singular matrix there: a stretch the run went through on an equivalent model), the
interpolated state is kept and counted.  The model's outputs are evaluated at the states.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..integrate.calls import SolveState, adaptive_args, rows_for
from ..integrate.methods import KUTTA_MERSON_ADAPTIVE, Tableau
from ..kernel.built import built
from ..kernel.constants import STATS_RCOND_C, STATS_RCOND_J2, STATS_RCOND_T, STATS_VIOL, STATUS_OK
from .plan import Plan
from .result import Run

__all__ = ["POINTS", "Sampled", "interpolate", "sample"]

#: refined rows the interpolating polynomial goes through (degree POINTS − 1)
POINTS = 8
#: attempted steps of one re-integration between two refined rows
MAX_ATTEMPTS = 10_000
#: interpolated times computed at once (a POINTS × POINTS array per time)
_CHUNK = 20_000


class Sampled:
    """The states at the asked times (by name, as ``Run.state``), and how many were stepped to
    (``stepped``) or kept interpolated where stepping failed (``unchecked``)."""

    def __init__(self, state: dict[str, np.ndarray], stepped: int, unchecked: int):
        self.state, self.stepped, self.unchecked = state, stepped, unchecked


def sample(plan: Plan, ref: Run, t: np.ndarray) -> Sampled:
    """The states of ``ref`` (a run of ``plan`` that kept every step) at times ``t`` (within its
    rows, increasing)."""
    info = plan.info
    names = list(info.state_names)
    tr = ref.t
    keep = np.concatenate([[True], np.diff(tr) > 0])  # a repeated time (a kept last row) once
    tr = tr[keep]
    XR = np.column_stack([ref.state[k][keep] for k in names])
    X = interpolate(tr, XR, t)
    lower = interpolate(tr, XR, t, POINTS - 1)
    tol = plan.atol + plan.rtol * np.abs(X)
    doubtful = np.flatnonzero(np.any(np.abs(X - lower) > tol, axis=1))
    stepped = unchecked = 0
    if doubtful.size:
        stepper = _Stepper(plan)
        before = np.clip(np.searchsorted(tr, t[doubtful], side="right") - 1, 0, tr.size - 1)
        for i, r in zip(doubtful, before, strict=True):
            y = stepper.step(float(tr[r]), XR[r], float(t[i]))
            if y is None:
                unchecked += 1
            else:
                X[i], stepped = y, stepped + 1
    state = {k: X[:, j] for j, k in enumerate(names)}
    module = built(plan.system).module(plan.variant)
    if module.NO:
        O = np.empty((t.size, module.NO))
        module.outputs_rows(t, np.ascontiguousarray(X), plan.p, O)
        state.update({k: O[:, j] for j, k in enumerate(info.outputs)})
    return Sampled(state, stepped, unchecked)


class _Stepper:
    """A state stepped from one time to another with an embedded pair at the plan's tolerances."""

    def __init__(self, plan: Plan):
        job = plan.job()
        method = plan.integrator if isinstance(plan.integrator, Tableau) else KUTTA_MERSON_ADAPTIVE
        # only the last row is written (every: never before it); no forces, no switching
        self.job = replace(job, method=method, every=1 << 62, alternatives=(), forces=False)
        self.rows = rows_for(self.job, self.job.module, 1)

    def step(self, t0: float, x0: np.ndarray, t: float) -> np.ndarray | None:
        """x0 at t0 advanced to t, or None where the steps fail."""
        if t <= t0:
            return x0.copy()
        job = self.job
        x = x0.copy()
        stats = np.zeros(STATS_VIOL + job.module.NV)
        stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = stats[STATS_RCOND_C] = 1.0
        args = adaptive_args(
            job, job.p, x, self.rows, stats, t=t0, h=t - t0, max_steps=MAX_ATTEMPTS, accepted=0,
            rcond_min=job.rcond_min, t_final=t, solve=SolveState(job, job.module), bounded=False,
        )  # fmt: skip
        status, t_end = job.module.integrate_adaptive(*args)[:2]
        return x if status == STATUS_OK and t_end >= t and np.all(np.isfinite(x)) else None


def interpolate(tr: np.ndarray, XR: np.ndarray, t: np.ndarray, points: int = POINTS) -> np.ndarray:
    """The rows ``XR`` at times ``tr`` (increasing) interpolated to times ``t`` (within them): at
    each t the Lagrange polynomial through the ``points`` rows nearest it (as many on each side
    as there are); a time of ``tr`` gives its row exactly."""
    out = np.empty((t.size, XR.shape[1]))
    P = max(1, min(points, tr.size))
    offsets = np.arange(P)
    others = ~np.eye(P, dtype=bool)
    for a in range(0, t.size, _CHUNK):
        ts = t[a : a + _CHUNK]
        j = np.searchsorted(tr, ts)
        lo = np.clip(j - P // 2, 0, tr.size - P)
        idx = lo[:, None] + offsets  # (n, P)
        nodes = tr[idx]
        num = ts[:, None, None] - nodes[:, None, :]  # t − t_k, (n, i, k)
        den = nodes[:, :, None] - nodes[:, None, :]  # t_i − t_k
        ratio = np.where(others, num / np.where(others, den, 1.0), 1.0)
        w = np.prod(ratio, axis=2)  # the Lagrange basis l_i(t), (n, P)
        out[a : a + _CHUNK] = np.einsum("ni,nik->nk", w, XR[idx])
    return out
