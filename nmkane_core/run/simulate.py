"""Runs: settings in, a :class:`Run` (numpy arrays + summary) out.

:func:`resolve` checks a :class:`~nmkane_core.schema.RunSettings` against the system
(every error names the field, the value and what is allowed) and fills in the defaults;
:func:`simulate` integrates with the compiled kernel in chunks (progress bar, time limit,
cancellation between chunks) and never returns non-finite numbers: a run that hits a
singular J2 or T, or whose state stops being finite, ends with status ``singular`` or
``diverged`` and keeps everything computed up to the last good step.

The parts live in their own modules: settings checked in :mod:`nmkane_core.run.settings` and
resolved into a plan in :mod:`nmkane_core.run.plan`, the loop drivers in
:mod:`nmkane_core.integrate.drivers` (model switching in :mod:`nmkane_core.integrate.switching`,
the compiled loops' interface in :mod:`nmkane_core.kernel.interface`), the result made in
:mod:`nmkane_core.run.finish` (how runs end: :mod:`nmkane_core.run.endings`); this module runs them.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor

from ..declare.system import System
from ..integrate.drivers import integrate
from ..kernel import special
from ..kernel.built import built
from ..schema import RunSettings
from .accuracy import add_error_estimate, check_refined_budget
from .catalog import catalog
from .finish import finish
from .plan import Plan, resolve, validate_settings
from .result import Run

__all__ = [
    "Plan",
    "Run",
    "resolve",
    "simulate",
    "simulate_many",
    "kernel_for",
    "catalog",
    "prepare",
    "validate_settings",
]


def simulate(
    settings: RunSettings | Mapping | Plan,
    *,
    progress: bool | None = None,
    time_limit: float | None = None,
    cancel: Callable[[], bool] | None = None,
) -> Run:
    """Integrate one run and return it as a :class:`Run`.

    Parameters
    ----------
    settings:
        What to run: a :class:`~nmkane_core.schema.RunSettings`, a mapping with the same
        fields (``{"system": NAME, "dt": 0.001, "t_final": 10, "initial": {...}}``;
        omitted fields take the system's defaults), or a :class:`Plan` already made by
        :func:`resolve`.  Settings are checked before anything runs: bad input raises
        :class:`~nmkane_core.errors.InputError` naming the field, the value and what is
        allowed (an initial state the constraints cannot be solved from is such input).
    progress:
        Show a progress bar on stderr (default: when stderr is a terminal).
    time_limit:
        Wall-clock seconds of integration (compiling or loading the kernel is not counted;
        it is reported as ``summary["kernel_load_s"]``); the run then ends ``timeout``.
    cancel:
        A function polled between chunks of compiled work; when it returns true the run
        ends ``timeout`` with the message "cancelled".

    Returns
    -------
    Run
        ``t``, ``state`` (by coordinate and speed name, plus the model's outputs),
        ``energy`` (None when the model declares none), ``violation`` (φ and ψ by
        constraint name, then monitors), ``settings`` (fully resolved) and ``summary``:
        ``status`` — ``"ok"`` (reached t_final), ``"event"`` (a declared event fired),
        ``"singular"`` (J2 or T became singular or ill-conditioned: reciprocal condition estimate ≤ ``rcond_min``),
        ``"diverged"`` (the state or its derivative stopped being finite: an unstable
        step, or the model's expressions undefined where the motion went — a square root
        of a negative number, a zero denominator), ``"timeout"`` (time limit or
        cancellation) or ``"failed"`` (step size below its minimum, step or row budget
        used up, a projection or scipy failure) — and ``message`` saying why, with
        steps, evaluations, wall time, ``t_end``, maxima of |violation| and of the
        energy drift, the smallest condition estimates, model switches and warnings.
        A system that declares events (:mod:`nmkane_core.run.events`) ends ``"event"`` at the
        first one that fires, with ``summary["event"] = {"name": ..., "t": ...}``.
        A run that asks ``error_estimate`` is made a second time, refined, and
        ``summary["error_estimate"]`` compares the two (:mod:`nmkane_core.run.accuracy`); both
        runs count against ``time_limit``.

    Guarantees: every number returned is finite (a run that cannot go on stops and keeps
    what was computed up to its last good step); output is bounded by
    ``LIMITS["max_rows"]`` rows and ``LIMITS["max_steps"]`` steps; numerical trouble during
    integration is a status, never an exception.
    """
    plan = settings if isinstance(settings, Plan) else resolve(settings)
    check_refined_budget(plan)  # error_estimate's second run within the step budget too
    t_setup = time.perf_counter()
    job = plan.job()
    if evaluations(plan) > special.MIN_EVALUATIONS:  # long work: the model's own build, in the background
        job.module.specialize()
    setup = time.perf_counter() - t_setup
    if progress is None:
        progress = sys.stderr.isatty()
    bar = _Progress(plan.t_final, progress)
    start = time.perf_counter()
    try:
        out = integrate(job, bar, time_limit, cancel)
    finally:
        bar.close()
    run = finish(plan, out, time.perf_counter() - start, setup)
    if plan.settings.get("error_estimate"):  # a second run, refined (nmkane_core.run.accuracy)
        left = None if time_limit is None else max(0.0, time_limit - (time.perf_counter() - start))
        add_error_estimate(run, plan, simulate, progress=progress, time_left=left, cancel=cancel)
    return run


def prepare(plan: Plan):
    """Load — or, on a model's first use, derive and compile — every kernel ``simulate(plan)``
    runs (the CLI does this under a "first use" notice); returns the chosen variant's kernel."""
    return plan.job().module


def evaluations(plan: Plan) -> int:
    """The right-hand sides a run is expected to take: its steps times the method's stages (an
    adaptive or scipy run: as many as at the system's default step)."""
    method = plan.integrator
    step = plan.dt if method.kind == "fixed" else plan.system.default_dt
    return int(plan.t_final / step) * max(1, getattr(method, "stages", 1))


def kernel_for(system: System, variant: str | None):
    """The compiled kernel module of a system's variant (loaded from cache or built once)."""
    return built(system).module(variant)


def simulate_many(
    settings_list, *, workers: int | None = None, progress: bool | None = None, time_limit: float | None = None
) -> list[Run]:
    """Many runs (a Γ sweep, a parameter study) spread over the machine's cores.

    The compiled loops release the GIL, so a thread pool runs them in parallel; every run
    is resolved (and so checked) before any starts.  Results keep the input order.
    """
    plans = [s if isinstance(s, Plan) else resolve(s) for s in settings_list]
    work: dict[int, int] = {}
    for pl in plans:
        module = kernel_for(pl.system, pl.variant)
        work[id(module)] = work.get(id(module), 0) + evaluations(pl)
        if work[id(module)] > special.MIN_EVALUATIONS:
            module.specialize()
    workers = workers or os.cpu_count() or 1
    if progress is None:
        progress = sys.stderr.isatty()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(plans), unit="run", delay=1.0, leave=False, desc="runs")
    results: list[Run | None] = [None] * len(plans)

    def one(i):
        results[i] = simulate(plans[i], progress=False, time_limit=time_limit)
        if bar is not None:
            bar.update(1)

    try:
        if workers == 1:
            for i in range(len(plans)):
                one(i)
        else:
            with ThreadPoolExecutor(max_workers=workers) as pool:
                list(pool.map(one, range(len(plans))))
    finally:
        if bar is not None:
            bar.close()
    return [r for r in results if r is not None]


class _Progress:
    """The progress bar of one run on stderr (tqdm): shown once a run has taken ``DELAY`` s.

    ``update`` goes through tqdm's own ``update`` (not ``refresh``), which keeps its delay
    and its record of what was printed, so a short run prints nothing and ``close`` clears
    the bar it drew.  A terminal that reports zero columns (some pseudo-terminals: ``script``,
    container consoles) gets a bar of ``FALLBACK_COLUMNS``: tqdm would take it as −1 rows and draw nothing.
    """

    DELAY = 1.0
    FALLBACK_COLUMNS = 100

    def __init__(self, total: float, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            try:
                columns = os.get_terminal_size(sys.stderr.fileno()).columns
            except (OSError, ValueError, AttributeError):
                columns = 0
            self.bar = tqdm(
                total=total,
                unit="s",
                unit_scale=False,
                delay=self.DELAY,
                leave=False,
                mininterval=0.25,
                ncols=None if columns else self.FALLBACK_COLUMNS,
                nrows=None if columns else 24,  # tqdm reads 0 rows as -1: draws nothing
                desc="simulating",
                bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]",
            )

    def update(self, t: float):
        if self.bar is not None and t > self.bar.n:
            self.bar.update(t - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()
