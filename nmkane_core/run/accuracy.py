"""The estimated global error of a run (``RunSettings.error_estimate``): the run repeated, refined.

A run's tolerances bound the error its method makes in one step, not how far the state has
drifted from the exact motion after many; a small constraint violation or energy drift does
not bound it either (a projection or Baumgarte terms keep them small whatever the error along
the constraint manifold).  The estimate compares the run with a second run of the same
settings, refined:

* fixed-step methods (``half step``): dt/2 and ``every`` × 2, so the refined run's output rows
  fall on the run's times exactly (step i of the run is step 2i of the refined one); for a
  method of order p the difference is (1 − 2^−p) of the run's error when that error is C h^p,
  so Richardson's max_abs × 2^p/(2^p − 1) is reported too;
* adaptive and scipy methods (``tolerance / 10``): rtol/10 and atol/10, every step kept
  (``every`` = 1), and the refined run's states at the run's times from
  :func:`~nmkane_core.run.sampling.sample` (interpolated by degree-7 polynomials through the
  refined rows, checked, and stepped to at the refined tolerances where the check fails).  The
  refined run's error is about a tenth of the run's (tolerance proportionality), so the
  difference is about 0.9 of the run's error; no factor is claimed.

The estimate is the largest |x − x_refined| of each state (and model output) over the rows
compared.  Both runs must reach their end (status ``ok`` or ``event``); otherwise the summary
says which did not, and why, instead of giving numbers.  Both count against the run's time
limit.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..schema import LIMITS, ErrorEstimate
from .plan import Plan, round_up
from .result import Run
from .sampling import POINTS, sample

__all__ = ["add_error_estimate", "check_refined_budget", "compare", "refined_plan", "refined_steps"]

#: the statuses of a run that reached its end
DONE = ("ok", "event")
#: a refined rtol below this is refused: rounding, not truncation, would make the difference
MIN_RTOL = 100 * np.finfo(float).eps

#: runs a plan (``simulate``): (plan, progress, time_limit, cancel) -> Run
Rerun = Callable[..., Run]


def refined_plan(plan: Plan) -> tuple[Plan, str, dict[str, float]]:
    """(the refined run's plan, its method's name, the settings that differ) for ``plan``.

    The refined run reports no constraint forces (not compared) and asks no estimate of its own."""
    fixed = plan.integrator.kind == "fixed"
    dt, every = (plan.dt / 2, 2 * plan.every) if fixed else (plan.dt, 1)  # adaptive: every step kept
    rtol, atol = (plan.rtol, plan.atol) if fixed else (plan.rtol / 10, plan.atol / 10)
    # adaptive: the refined rows are interpolated to the run's times, not asked at them
    output_times = plan.output_times if fixed else None
    how = "half step" if fixed else "tolerance / 10"
    changed: dict[str, float] = {"dt": dt, "every": every} if fixed else {"rtol": rtol, "atol": atol, "every": every}
    settings = {
        **plan.settings,
        **changed,
        "output_times": None if output_times is None else list(output_times),
        "error_estimate": False,
        "constraint_forces": False,
    }
    refined = replace(
        plan, dt=dt, every=every, rtol=rtol, atol=atol, output_times=output_times, settings=settings, forces=False
    )
    return refined, how, changed


def add_error_estimate(
    run: Run,
    plan: Plan,
    rerun: Rerun,
    *,
    progress: bool | None = None,
    time_left: float | None = None,
    cancel: Callable[[], bool] | None = None,
) -> None:
    """Set ``run.summary["error_estimate"]``: run ``plan`` refined (with ``rerun``, within
    ``time_left`` s) and compare (see the module docstring)."""
    refined, how, changed = refined_plan(plan)
    fixed = plan.integrator.kind == "fixed"
    est: dict = {"method": how, "refined": changed, "order": plan.integrator.order if fixed else None}
    why = _not_run(run, plan, refined)
    if why is not None:
        est["message"] = why
    else:
        ref = rerun(refined, progress=progress, time_limit=time_left, cancel=cancel)
        est.update(refined_status=ref.status, steps=ref.summary["steps"], wall_time_s=ref.summary["wall_time_s"])
        if ref.status not in DONE:
            est["message"] = f"no estimate: the refined run ({_what(how, changed)}) ended {ref.status}: " + str(
                ref.summary["message"]
            )
        else:
            est.update(_estimate(run, ref, refined, how, changed))
    run.summary["error_estimate"] = ErrorEstimate.model_validate(est).model_dump(mode="json")


def _not_run(run: Run, plan: Plan, refined: Plan) -> str | None:
    """Why the refined run is not made (None: it is)."""
    if run.status not in DONE:
        return f"no estimate: the run ended {run.status} (the estimate compares runs that reach their end)"
    if plan.integrator.kind != "fixed" and refined.rtol < MIN_RTOL:
        return (
            f"no estimate: rtol/10 = {refined.rtol:.3g} is below 100ε = {MIN_RTOL:.3g}, where rounding errors, "
            f"not the method's, would make the difference (take rtol ≥ {10 * MIN_RTOL:.3g})"
        )
    return None


def refined_steps(plan: Plan) -> int:
    """The steps of a fixed-step run's refined run (at dt/2); 0 for other methods."""
    if plan.integrator.kind != "fixed":
        return 0
    return math.ceil(plan.t_final / (plan.dt / 2) - 1e-9)


def check_refined_budget(plan: Plan, max_steps: int | None = None, where: str = "") -> None:
    """Refuse a fixed-step run that asks ``error_estimate`` when its refined run at dt/2 would take
    more than ``max_steps`` steps (default: the library's, ``LIMITS["max_steps"]``; ``where``: whose
    limit, e.g. " on this service"): an :class:`~nmkane_core.errors.InputError` naming
    ``error_estimate`` and the dt that would do, before anything runs."""
    max_steps = LIMITS["max_steps"] if max_steps is None else max_steps
    steps = refined_steps(plan)
    if plan.settings.get("error_estimate") and steps > max_steps:
        raise InputError(
            "error_estimate",
            True,
            f"false, or dt ≥ {round_up(2 * plan.t_final / max_steps):.3g} s for t_final = {plan.t_final:g} s (the "
            f"estimate's second run, at dt/2, within {max_steps:,} steps{where})",
            f"its second run at dt/2 would take {steps:,} steps",
        )


def _what(how: str, changed: dict[str, float]) -> str:
    if how == "half step":
        return f"dt/2 = {changed['dt']:.6g} s"
    return f"rtol = {changed['rtol']:.3g}, atol = {changed['atol']:.3g}"


def _estimate(run: Run, ref: Run, refined: Plan, how: str, changed: dict[str, float]) -> dict:
    """The numbers of a run and its refined run (of plan ``refined``) that both reached their end."""
    fixed = refined.integrator.kind == "fixed"
    names = [k for k in run.state if k in ref.state]
    rows, diff, how_sampled = compare(run, ref, refined, names)
    if rows == 0:
        return {"message": "no estimate: the two runs have no output time in common"}
    if not np.all(np.isfinite(diff)):
        return {"rows": rows, "message": "no estimate: the difference of the two runs overflowed"}
    max_abs = {k: float(v) for k, v in zip(names, diff, strict=True)}
    est: dict = {"rows": rows, "max_abs": max_abs}
    est["message"] = f"largest |x − x_refined| over {rows:,} output times, against a run at {_what(how, changed)}"
    est["message"] += f" ({how_sampled})"
    if fixed:
        p = refined.integrator.order
        est["richardson"] = {k: v * 2.0**p / (2.0**p - 1.0) for k, v in max_abs.items()}
        est["message"] += f"; Richardson ×{2**p}/{2**p - 1} for order {p}"
    return est


def compare(run: Run, ref: Run, refined: Plan, names: list[str]) -> tuple[int, np.ndarray, str]:
    """(rows compared, the largest |run − ref| of each state in ``names``, how the refined run
    was sampled) for ``ref``, the run of ``refined``.

    Fixed-step runs: the rows whose times the refined run has too (all of them, but the last row
    of a run cut at an event at a time of its own).  Adaptive runs: every row within the refined
    run's span, the refined states there from :func:`~nmkane_core.run.sampling.sample`."""
    t, tr = run.t, ref.t
    X = np.column_stack([run.state[k] for k in names])
    scale = np.maximum(1.0, np.abs(t))
    if refined.integrator.kind == "fixed":
        j = np.clip(np.searchsorted(tr, t), 0, tr.size - 1)
        back = np.clip(j - 1, 0, tr.size - 1)
        j = np.where(np.abs(tr[back] - t) < np.abs(tr[j] - t), back, j)
        same = np.abs(tr[j] - t) <= 1e-9 * scale
        if not same.any():
            return 0, np.zeros(len(names)), ""
        XR = np.column_stack([ref.state[k][j[same]] for k in names])
        return int(same.sum()), np.max(np.abs(X[same] - XR), axis=0), "the same output times"
    inside = t <= tr[-1] + 1e-12 * scale
    if not inside.any():
        return 0, np.zeros(len(names)), ""
    at = sample(refined, ref, t[inside])
    XR = np.column_stack([at.state[k] for k in names])
    note = f"its states interpolated to the run's times by degree-{POINTS - 1} polynomials"
    if at.stepped:
        note += f", {at.stepped:,} of them stepped to at its tolerances where the polynomials disagreed"
    if at.unchecked:
        note += f", {at.unchecked:,} interpolated where stepping failed"
    return int(inside.sum()), np.max(np.abs(X[inside] - XR), axis=0), note
