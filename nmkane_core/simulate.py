"""Runs: settings in, a :class:`Run` (numpy arrays + summary) out.

:func:`resolve` checks a :class:`~nmkane_core.schema.RunSettings` against the system
(every error names the field, the value and what is allowed) and fills in the defaults;
:func:`simulate` integrates with the compiled kernel in chunks (progress bar, time limit,
cancellation between chunks) and never returns non-finite numbers: a run that hits a
singular J2 or T, or whose state stops being finite, ends with status ``singular`` or
``diverged`` and keeps everything computed up to the last good step.
"""

from __future__ import annotations

import csv
import io
import math
import os
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from .errors import InputError
from .initial import initial_state
from .integrators import ScipyMethod, Tableau, get_integrator
from .projection import ProjectionOptions, projection_options
from .schema import LIMITS, RunResult, RunSettings, RunSummary
from .registry import get_system
from .system import System

__all__ = ["Plan", "Run", "resolve", "simulate", "simulate_many", "kernel_for", "catalog"]



# --------------------------------------------------------------------------- plan
@dataclass
class Plan:
    """A fully resolved, checked run request."""

    system: System
    variant: str
    integrator: Tableau | ScipyMethod
    params: dict[str, float]
    p: np.ndarray
    G: np.ndarray
    G1: np.ndarray
    G2: np.ndarray
    dt: float
    t_final: float
    every: int
    rtol: float
    atol: float
    rcond_min: float
    rcond_switch: float
    switching: bool
    projection: "ProjectionOptions"
    x0: np.ndarray
    initial: dict[str, float]
    settings: dict
    warnings: list[str] = field(default_factory=list)
    initial_correction: dict[str, float] = field(default_factory=dict)

    @property
    def info(self):
        return self.system.info(self.variant)


def validate_settings(settings: Mapping) -> RunSettings:
    """The schema's checks (types, finite numbers, ranges) with errors as :class:`InputError`."""
    from pydantic import ValidationError

    try:
        return RunSettings.model_validate(dict(settings))
    except ValidationError as e:
        err = e.errors()[0]
        field = ".".join(str(p) for p in err["loc"]) or "settings"
        raise InputError(field, err.get("input"), err["msg"].replace("Input should be", "a value")) from None


def _check_float(name, value, lo, hi, lo_open=True, unit=""):
    v = float(value)
    ok = (v > lo if lo_open else v >= lo) and v <= hi and math.isfinite(v)
    if not ok:
        bracket = "(" if lo_open else "["
        raise InputError(name, value, f"a finite number in {bracket}{lo:g}, {hi:g}]{' ' + unit if unit else ''}",
                         "out of range" if math.isfinite(v) else "not finite")
    return v


def _gain(name: str, value, size: int, warnings: list[str], what: str) -> np.ndarray:
    if value is None:
        return np.zeros((size, size))
    if isinstance(value, (int, float)):
        g = _check_float(name, value, -LIMITS["max_gain"], LIMITS["max_gain"], lo_open=False)
        G = g * np.eye(size)
    else:
        try:
            G = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(name, value, f"a number or a {size}×{size} matrix", "not a matrix") from None
        if G.shape != (size, size):
            raise InputError(name, value, f"a number or a {size}×{size} matrix ({what})",
                             f"shape {G.shape}")
        if not np.all(np.isfinite(G)) or np.abs(G).max(initial=0) > LIMITS["max_gain"]:
            raise InputError(name, value, f"finite entries with |Γ_ij| ≤ {LIMITS['max_gain']:g}", "out of range")
    if size == 0 and value not in (None, 0, 0.0):
        warnings.append(f"{name} = {value!r} ignored: {what}")
    return G


def resolve(settings: RunSettings | Mapping) -> Plan:
    """Check settings against the system and fill in defaults."""
    if not isinstance(settings, RunSettings):
        settings = validate_settings(settings)
    s = settings
    system = get_system(s.system)
    other = "formulation" if system.option == "model" else "model"
    if getattr(s, other) is not None:
        raise InputError(other, getattr(s, other),
                         f"{system.option}: {' | '.join(system.variants)} ({system.name} has no {other})",
                         f"{system.name} has no {other}")
    variant = system.check_variant(getattr(s, system.option), system.option)
    integ = get_integrator(s.integrator or system.default_integrator)
    dt = _check_float("dt", s.dt if s.dt is not None else system.default_dt,
                      0.0, LIMITS["max_dt"], unit="s")
    if dt < LIMITS["min_dt"]:
        raise InputError("dt", dt, f"a number in [{LIMITS['min_dt']:g}, {LIMITS['max_dt']:g}] s", "too small")
    t_final = _check_float("t_final", s.t_final if s.t_final is not None else system.default_t_final,
                           0.0, LIMITS["max_t_final"], unit="s")
    if s.every < 1 or s.every > LIMITS["max_steps"]:
        raise InputError("every", s.every, f"an integer in [1, {LIMITS['max_steps']}]")
    nsteps = math.ceil(t_final / dt - 1e-9)
    if isinstance(integ, Tableau) and not integ.adaptive:
        if nsteps > LIMITS["max_steps"]:
            raise InputError("dt", dt, f"t_final/dt ≤ {LIMITS['max_steps']:,} steps "
                             f"(dt ≥ {t_final / LIMITS['max_steps']:.3g} s for t_final = {t_final:g} s)",
                             f"{nsteps:,} steps")
        rows = nsteps // s.every + 2
        if rows > LIMITS["max_rows"]:
            raise InputError("every", s.every, f"an integer ≥ {math.ceil(nsteps / LIMITS['max_rows'])} "
                             f"(at most {LIMITS['max_rows']:,} output rows)", f"{rows:,} rows")
    rtol = _check_float("rtol", s.rtol, 0.0, 0.1)
    if rtol < 1e-14:
        raise InputError("rtol", s.rtol, "a number in [1e-14, 0.1]", "too small")
    atol = _check_float("atol", s.atol, 0.0, 1.0)
    rcond_min = _check_float("rcond_min", s.rcond_min, 0.0, 0.1, lo_open=False)
    rcond_switch = _check_float("rcond_switch", s.rcond_switch, 0.0, 0.5, lo_open=False)
    params = system.resolve_params(s.params)
    p = system.param_vector(variant, params)
    md = system.info(variant)
    warnings: list[str] = []
    m_nh, m_h = len(md.nonholonomic), len(md.holonomic)
    G = _gain("gamma", s.gamma if s.gamma is not None else system.default_gamma, m_nh, warnings,
              f"the {variant} {system.option} has no nonholonomic constraints")
    G1 = _gain("gamma1", s.gamma1 if s.gamma1 is not None else system.default_gamma1, m_h, warnings,
               f"the {variant} {system.option} has no holonomic constraints")
    G2 = _gain("gamma2", s.gamma2 if s.gamma2 is not None else system.default_gamma2, m_h, warnings,
               f"the {variant} {system.option} has no holonomic constraints")
    _warn_unstable(G, G1, G2, warnings)
    proj = projection_options(s.projection, s.projection_weight, s.projection_iterations,
                              s.projection_jacobian, s.projection_energy)
    if proj.name != "none" and isinstance(integ, ScipyMethod):
        raise InputError("projection", s.projection, "none with scipy integrators; blajer | yoon with "
                         "rk4, kutta-merson, kutta-merson-adaptive", "post-step projection needs a tableau integrator")
    if proj.name != "none" and md.m == 0:
        warnings.append(f"projection {proj.name} has nothing to do: the {variant} {system.option} has no constraints")
    correction: dict[str, float] = {}
    x0, full = initial_state(system, variant, params, dict(s.initial), project=s.project_initial,
                             correction=correction)
    if correction:
        warnings.append("the initial state was projected onto the constraint manifold: "
                        + ", ".join(f"{k} {v:+.3g}" for k, v in correction.items()))
    resolved = s.model_dump()
    resolved.update({system.option: variant, other: None, "integrator": integ.name, "dt": dt,
                     "t_final": t_final, "params": params, "initial": full,
                     "gamma": _plain(s.gamma, system.default_gamma),
                     "gamma1": _plain(s.gamma1, system.default_gamma1),
                     "gamma2": _plain(s.gamma2, system.default_gamma2)})
    if proj.name != "none":
        resolved.update(projection_weight=proj.weight, projection_iterations=proj.iterations,
                        projection_jacobian=proj.jacobian, projection_energy=proj.energy)
    plan = Plan(system, variant, integ, params, p, G, G1, G2, dt, t_final, s.every, rtol, atol,
                rcond_min, rcond_switch, s.switching, proj, x0, full, resolved, warnings)
    plan.initial_correction = correction
    return plan


def _plain(v, default):
    return default if v is None else v


def _warn_unstable(G, G1, G2, warnings):
    if G.size and np.any(G) and np.any(np.linalg.eigvals(G).real >= 0):
        warnings.append("Γ has eigenvalues with non-negative real part: the nonholonomic constraint "
                        "error dynamics φ̇ = Γφ are not stable (stabilizing gains are negative)")
    if G1.size and (np.any(G1) or np.any(G2)):
        k = G1.shape[0]
        comp = np.block([[np.zeros((k, k)), np.eye(k)], [G2, G1]])
        if np.any(np.linalg.eigvals(comp).real >= 0):
            warnings.append("Γ1, Γ2 give constraint error dynamics ψ̈ = Γ1ψ̇ + Γ2ψ with eigenvalues of "
                            "non-negative real part: not stable (e.g. Γ1 = −20, Γ2 = −100 are)")


# --------------------------------------------------------------------------- kernels
def kernel_for(system: System, variant: str):
    """The compiled kernel module of a system's variant (loaded from cache or built once)."""
    return system.kernel(variant)[0]


# --------------------------------------------------------------------------- result
@dataclass
class Run:
    """A finished run: arrays by name and the summary (convert with :meth:`document`)."""

    system: str
    settings: dict
    t: np.ndarray
    state: dict[str, np.ndarray]
    energy: np.ndarray | None
    violation: dict[str, np.ndarray]
    summary: dict

    @property
    def status(self) -> str:
        return self.summary["status"]

    def document(self, id: str | None = None) -> RunResult:
        return RunResult(
            id=id, system=self.system, settings=self.settings, t=self.t.tolist(),
            state={k: v.tolist() for k, v in self.state.items()},
            energy=None if self.energy is None else self.energy.tolist(),
            violation={k: v.tolist() for k, v in self.violation.items()},
            summary=RunSummary(**self.summary))

    def columns(self) -> dict[str, np.ndarray]:
        cols = {"t": self.t, **self.state}
        if self.energy is not None:
            cols["energy"] = self.energy
        cols.update({f"violation_{k}": v for k, v in self.violation.items()})
        return cols

    def to_csv(self) -> str:
        cols = self.columns()
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for row in zip(*[c.tolist() for c in cols.values()]):
            w.writerow([repr(v) for v in row])
        return buf.getvalue()

    def save(self, path: str) -> None:
        """Write ``.json`` (the run document), ``.csv`` or ``.npz``."""
        if path.endswith(".json"):
            with open(path, "w") as f:
                f.write(self.document().model_dump_json(by_alias=True))
        elif path.endswith(".csv"):
            with open(path, "w") as f:
                f.write(self.to_csv())
        elif path.endswith(".npz"):
            import json
            np.savez_compressed(path, **self.columns(),
                                summary=json.dumps(self.summary), settings=json.dumps(self.settings))
        else:
            raise InputError("out", path, "a file name ending in .json, .csv or .npz", "unknown format")


# --------------------------------------------------------------------------- simulate
def simulate(settings: RunSettings | Mapping | Plan, *, progress: bool | None = None,
             time_limit: float | None = None, cancel: Callable[[], bool] | None = None) -> Run:
    """Run a simulation; see the module docstring for the guarantees."""
    plan = settings if isinstance(settings, Plan) else resolve(settings)
    t_setup = time.perf_counter()
    mod = prepare(plan)
    start = time.perf_counter()
    setup = start - t_setup
    if progress is None:
        progress = sys.stderr.isatty()
    bar = _Progress(plan.t_final, progress)
    try:
        if isinstance(plan.integrator, ScipyMethod):
            raw = _run_scipy(plan, mod, bar, start, time_limit, cancel)
        elif plan.integrator.adaptive:
            raw = _run_adaptive(plan, mod, bar, start, time_limit, cancel)
        else:
            raw = _run_fixed(plan, mod, bar, start, time_limit, cancel)
    finally:
        bar.close()
    run = _finish(plan, mod, raw, time.perf_counter() - start)
    run.summary["kernel_load_s"] = setup
    return run


def simulate_many(settings_list, *, workers: int | None = None, progress: bool | None = None,
                  time_limit: float | None = None) -> list[Run]:
    """Many runs (a Γ sweep, a parameter study) spread over the machine's cores.

    The compiled loops release the GIL, so a thread pool runs them in parallel; every run
    is resolved (and so checked) before any starts.  Results keep the input order.
    """
    plans = [s if isinstance(s, Plan) else resolve(s) for s in settings_list]
    for pl in plans:
        kernel_for(pl.system, pl.variant)
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
    return results


class _Progress:
    def __init__(self, total: float, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="s", unit_scale=False, delay=1.0, leave=False,
                            desc="simulating", bar_format="{desc}: {percentage:3.0f}%|{bar}| "
                            "t = {n:.4g}/{total:.4g} s [{elapsed}<{remaining}]")

    def update(self, t: float):
        if self.bar is not None:
            self.bar.n = t
            self.bar.refresh()

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _stats0(plan, mod):
    nv = mod.NV
    E0 = np.empty(1)
    V0 = np.empty((1, nv))
    mod.diagnostics_rows(np.zeros(1), plan.x0[None, :], plan.p, E0, V0)
    stats = np.zeros(5 + nv)
    stats[0] = E0[0]
    stats[3] = stats[4] = 1.0
    stats[5:] = np.abs(V0[0])
    return stats, E0[0], V0[0]


def prepare(plan: Plan):
    """Load — or, on a model's first use, compile — everything ``simulate(plan)`` runs, so
    that the run itself starts at once (the CLI does this under a "first use" notice).
    Returns the kernel module."""
    mod = kernel_for(plan.system, plan.variant)
    _prime(plan, mod)
    return mod


def _prime(plan: Plan, mod) -> None:
    """Call the run's compiled loop once with no work, so that a first run compiles (or
    loads from the disk cache) before its clock starts: ``time_limit`` bounds integration,
    not compilation, and the time shows as ``kernel_load_s``.  Argument types are exactly
    those of the real calls below (numba compiles one copy per type signature)."""
    from . import precompile

    precompile.wait(mod)                   # a new kernel's loop may be compiling next door
    tab = plan.integrator
    n2 = plan.x0.size
    if isinstance(tab, ScipyMethod):       # scipy calls the right-hand side and diagnostics
        mod.rhs_ws(0.0, plan.x0.copy(), plan.p, plan.G, plan.G1, plan.G2, np.empty((1, n2)), 0,
                   mod.make_workspace())
        mod.diagnostics(0.0, plan.x0.copy(), plan.p, np.empty(mod.NV))
        return
    x = plan.x0.copy()
    out_t, out_x = np.empty(1), np.empty((1, n2))
    out_E, out_V = np.empty(1), np.empty((1, mod.NV))
    stats = np.zeros(5 + mod.NV)
    proj = plan.projection.as_array(plan.info)
    if tab.adaptive:
        mod.integrate_adaptive(x, 0.0, plan.t_final, 0.1, plan.rtol, plan.atol, 1e-13, 1.0, 0, 1, 0,
                               plan.p, plan.G, plan.G1, plan.G2, tab.A, tab.b, tab.E, tab.c, 0.2, 0.0,
                               proj, out_t, out_x, out_E, out_V, stats)
    else:
        mod.integrate_fixed(x, 0.0, plan.dt, plan.t_final, 0, 0, 1, 1, plan.p, plan.G, plan.G1, plan.G2,
                            tab.A, tab.b, tab.c, 0.0, proj, out_t, out_x, out_E, out_V, 0, stats)


def _interrupted(start, time_limit, cancel):
    if cancel is not None and cancel():
        return "cancelled"
    if time_limit is not None and time.perf_counter() - start > time_limit:
        return "timeout"
    return None


class _Switcher:
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
    SWITCHED_CHUNK = 25          # steps per call while switched, to return promptly

    def __init__(self, plan: Plan, home):
        self.plan = plan
        self.home = home
        self.cur = home
        self.cur_name = plan.variant
        self.alts = list(plan.system.equivalents.get(plan.variant, ())) if plan.switching else []
        self.no_cure = False
        self.switches: list[dict] = []
        self.segments: list[tuple[int, int]] = []   # output rows computed with another model
        self.seg_start = 0

    @property
    def switched(self) -> bool:
        return self.cur is not self.home

    @property
    def threshold(self) -> float:
        if self.alts and not self.switched and not self.no_cure:
            return max(self.plan.rcond_switch, self.plan.rcond_min)
        return self.plan.rcond_min

    def _rcond(self, mod, t, x):
        _, rc0, rc1 = mod.rhs(t, x, self.plan.p, self.plan.G, self.plan.G1, self.plan.G2)
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
            mod = kernel_for(self.plan.system, v)
            if self._rcond(mod, t, x) > self.plan.rcond_switch:
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
            self.switches.append({"t": float(t), "from": self.cur_name, "to": self.plan.variant,
                                  "rcond": float(rc_home)})
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
                stats[5:] = np.maximum(stats[5:], np.where(np.isfinite(seg), seg, 0.0).max(axis=0))


def _run_fixed(plan: Plan, mod, bar, start, time_limit, cancel):
    tab = plan.integrator
    dt, t_final, every = plan.dt, plan.t_final, plan.every
    nsteps = max(1, math.ceil(t_final / dt - 1e-9))
    rows = nsteps // every + (1 if nsteps % every else 0) + 2
    n2 = plan.x0.size
    out_t, out_x = np.empty(rows), np.empty((rows, n2))
    out_E, out_V = np.empty(rows), np.empty((rows, mod.NV))
    stats, E0, V0 = _stats0(plan, mod)
    out_t[0], out_x[0], out_E[0], out_V[0] = 0.0, plan.x0, E0, V0
    x = plan.x0.copy()
    row, k, status, stop = 1, 0, 0, None
    chunk = 2000
    sw = _Switcher(plan, mod)
    proj = plan.projection.as_array(plan.info)   # None without projection (see the loops)
    loop = "integrate_fixed"
    while k < nsteps:
        t_call = time.perf_counter()
        k_end = min(nsteps, k + (sw.SWITCHED_CHUNK if sw.switched else chunk))
        status, k, row = getattr(sw.cur, loop)(x, 0.0, dt, t_final, k, k_end, nsteps, every, plan.p,
                                               plan.G, plan.G1, plan.G2, tab.A, tab.b, tab.c,
                                               sw.threshold, proj, out_t, out_x, out_E, out_V, row, stats)
        elapsed = time.perf_counter() - t_call
        if not sw.switched:
            chunk = int(min(max(chunk * min(4.0, 0.05 / max(elapsed, 1e-6)), 500), 5_000_000))
        bar.update(min(k * dt, t_final))
        if status in (1, 2) and sw.leave(k * dt, x, row):
            status = 0
            continue
        if status != 0:
            break
        sw.maybe_return(k * dt, x, row)
        stop = _interrupted(start, time_limit, cancel)
        if stop and k < nsteps:
            break
    t_last = t_final if k >= nsteps and status == 0 else k * dt
    if row == 0 or out_t[row - 1] < t_last - 1e-12 * max(1.0, t_last):
        # keep the last good state even when thinning skipped it
        out_t[row], out_x[row] = t_last, x
        mod.diagnostics_rows(out_t[row:row + 1], out_x[row:row + 1], plan.p, out_E[row:row + 1],
                             out_V[row:row + 1])
        row += 1
    sw.finish(row, out_t, out_x, out_E, out_V, stats)
    return dict(status=status, stop=stop, t=out_t[:row], x=out_x[:row], E=out_E[:row], V=out_V[:row],
                stats=stats, steps=k, evals=k * tab.stages, t_end=t_last, switches=sw.switches)


def _run_adaptive(plan: Plan, mod, bar, start, time_limit, cancel):
    tab = plan.integrator
    t_final = plan.t_final
    n2 = plan.x0.size
    stats, E0, V0 = _stats0(plan, mod)
    ts, xs, Es, Vs = [np.zeros(1)], [plan.x0[None, :].copy()], [np.array([E0])], [V0[None, :].copy()]
    x = plan.x0.copy()
    t, h = 0.0, min(plan.dt, t_final)
    accepted = attempts = 0
    status, stop = 0, None
    cap = 4096
    hmin = 1e-13 * max(1.0, t_final)
    err_exp = 1.0 / (tab.error_order + 1)
    sw = _Switcher(plan, mod)
    proj = plan.projection.as_array(plan.info)   # None without projection (see the loops)
    nrows = 1
    while t < t_final:
        size = sw.SWITCHED_CHUNK if sw.switched else cap
        out_t, out_x = np.empty(size), np.empty((size, n2))
        out_E, out_V = np.empty(size), np.empty((size, mod.NV))
        budget = min(sw.SWITCHED_CHUNK if sw.switched else 200_000, LIMITS["max_steps"] - attempts)
        status, t, h, nrow, accepted, att = sw.cur.integrate_adaptive(
            x, t, t_final, h, plan.rtol, plan.atol, hmin, t_final, budget, plan.every, accepted,
            plan.p, plan.G, plan.G1, plan.G2, tab.A, tab.b, tab.E, tab.c, err_exp, sw.threshold,
            proj, out_t, out_x, out_E, out_V, stats)
        attempts += att
        ts.append(out_t[:nrow]); xs.append(out_x[:nrow]); Es.append(out_E[:nrow]); Vs.append(out_V[:nrow])
        nrows += nrow
        bar.update(t)
        if status in (1, 2) and sw.leave(t, x, nrows):
            status = 0
            continue
        if status == 5:
            status = 0
            if attempts >= LIMITS["max_steps"]:
                status = 4
                stop = "max_steps"
                break
        if status != 0:
            break
        sw.maybe_return(t, x, nrows)
        stop = _interrupted(start, time_limit, cancel)
        if stop and t < t_final:
            break
        stop = None
    if np.concatenate(ts)[-1] < t - 1e-12 * max(1.0, t):
        ts.append(np.array([t])); xs.append(x[None, :].copy())
        E, V = np.empty(1), np.empty((1, mod.NV))
        mod.diagnostics_rows(ts[-1], xs[-1], plan.p, E, V)
        Es.append(E); Vs.append(V)
        nrows += 1
    t_arr, x_arr, E_arr, V_arr = (np.concatenate(a) for a in (ts, xs, Es, Vs))
    sw.finish(nrows, t_arr, x_arr, E_arr, V_arr, stats)
    return dict(status=status, stop=stop, t=t_arr, x=x_arr, E=E_arr, V=V_arr, stats=stats, steps=accepted,
                evals=attempts * tab.stages, t_end=t, attempts=attempts, switches=sw.switches)


def _run_scipy(plan: Plan, mod, bar, start, time_limit, cancel):
    import scipy.integrate as si

    from .errors import SingularMatrix

    w = mod.make_workspace()
    n2 = plan.x0.size
    K = np.empty((1, n2))
    rcmin = [1.0, 1.0]

    def fun(t, x):
        mod.rhs_ws(t, np.ascontiguousarray(x, dtype=float), plan.p, plan.G, plan.G1, plan.G2, K, 0, w)
        rc0, rc1 = w[mod.ORC], w[mod.ORC + 1]
        rcmin[0], rcmin[1] = min(rcmin[0], rc0), min(rcmin[1], rc1)
        if rc0 <= plan.rcond_min:
            raise SingularMatrix("J2", rc0, t)
        if rc1 <= plan.rcond_min:
            raise SingularMatrix("T", rc1, t)
        return K[0].copy()

    stats, E0, V0 = _stats0(plan, mod)
    ts, xs = [0.0], [plan.x0.copy()]
    status, stop, nstep = 0, None, 0
    viol = np.empty(mod.NV)
    fail_msg = None
    try:
        solver = getattr(si, plan.integrator.solver)(fun, 0.0, plan.x0.copy(), plan.t_final,
                                                     rtol=plan.rtol, atol=plan.atol,
                                                     first_step=min(plan.dt, plan.t_final))
        while solver.status == "running":
            msg = solver.step()
            if solver.status == "failed":
                status, fail_msg = 4, msg
                break
            y = solver.y
            if not np.all(np.isfinite(y)):
                status = 3
                break
            nstep += 1
            E = mod.diagnostics(solver.t, y, plan.p, viol)
            if not (math.isfinite(E) and np.all(np.isfinite(viol))):
                status = 3
                break
            stats[1] = max(stats[1], abs(E - stats[0]))
            stats[2] = E - stats[0]
            stats[5:] = np.maximum(stats[5:], np.abs(viol))
            if nstep % plan.every == 0 or solver.status == "finished":
                ts.append(solver.t)
                xs.append(y.copy())
            if nstep >= LIMITS["max_steps"]:
                status, stop = 4, "max_steps"
                break
            if nstep % 200 == 0:
                bar.update(solver.t)
                stop = _interrupted(start, time_limit, cancel)
                if stop:
                    break
        nfev = solver.nfev
    except SingularMatrix as e:
        status = 1 if e.matrix == "J2" else 2
        nfev = 0
    stats[3], stats[4] = rcmin
    t_arr, x_arr = np.array(ts), np.array(xs)
    E_arr, V_arr = np.empty(len(ts)), np.empty((len(ts), mod.NV))
    mod.diagnostics_rows(t_arr, x_arr, plan.p, E_arr, V_arr)
    out = dict(status=status, stop=stop, t=t_arr, x=x_arr, E=E_arr, V=V_arr, stats=stats, steps=nstep,
               evals=nfev, t_end=float(t_arr[-1]))
    if fail_msg:
        out["fail_msg"] = fail_msg
    return out


def _finish(plan: Plan, mod, raw: dict, wall: float) -> Run:
    md = plan.info
    system = plan.system
    status_code, stop = raw["status"], raw.get("stop")
    t_end = raw["t_end"]
    stats = raw["stats"]
    if status_code == 0 and stop is None:
        status = "ok"
        message = (f"completed: {raw['steps']:,} steps of {plan.integrator.name} to t = {plan.t_final:g} s")
    elif status_code == 0 and stop in ("timeout", "cancelled"):
        status = "timeout"
        message = (f"stopped at t = {t_end:.6g} s: {'wall-time limit reached' if stop == 'timeout' else 'cancelled'}"
                   f"; results up to there are kept")
    elif status_code in (1, 2):
        status = "singular"
        which = "J2" if status_code == 1 else "T"
        rc = stats[3] if status_code == 1 else stats[4]
        message = (f"{which} became singular or ill-conditioned after t = {t_end:.6g} s "
                   f"(reciprocal condition estimate {rc:.3g} ≤ rcond_min = {plan.rcond_min:g}); "
                   f"the run stopped there and keeps the last good state")
        if plan.variant in system.singular_hints:
            message += f" — {system.singular_hints[plan.variant]}"
    elif status_code == 3:
        status = "diverged"
        message = (f"the state stopped being finite after t = {t_end:.6g} s; the run stopped and keeps "
                   f"the last finite state (try a smaller dt or gains of smaller magnitude)")
    elif status_code == 6:
        status = "failed"
        message = (f"the {plan.projection.name} projection met a singular correction matrix after "
                   f"t = {t_end:.6g} s; the run stopped there")
    else:
        status = "failed"
        message = raw.get("fail_msg") or (f"the step size fell below its minimum at t = {t_end:.6g} s"
                                          if stop != "max_steps" else
                                          f"the step budget ({LIMITS['max_steps']:,}) was used up at t = {t_end:.6g} s")
    x = raw["x"]
    state = {name: x[:, i].copy() for i, name in enumerate(md.state_names)}
    if mod.NO:
        O = np.empty((x.shape[0], mod.NO))
        mod.outputs_rows(raw["t"], x, plan.p, O)
        for i, name in enumerate(md.outputs):
            state[name] = O[:, i].copy()          # contiguous, like every other array
    state = {k: state[k] for k in system.state_names if k in state}
    viol_names = md.viol_names
    violation = {k: raw["V"][:, i].copy() for i, k in enumerate(viol_names)}
    has_energy = md.has_energy
    energy = raw["E"].copy() if has_energy else None
    summary = {
        "status": status, "message": message, "steps": int(raw["steps"]), "rhs_evals": int(raw["evals"]),
        "wall_time_s": wall, "t_end": float(t_end),
        "max_abs_violation": {k: float(stats[5 + i]) for i, k in enumerate(viol_names)},
        "max_abs_energy_drift": float(stats[1]) if has_energy else None,
        "final_energy_drift": float(energy[-1] - energy[0]) if has_energy else None,
        "min_rcond": {"J2": float(stats[3]), "T": float(stats[4])},
        "warnings": list(plan.warnings), "switches": raw.get("switches", []),
        "initial_correction": dict(plan.initial_correction),
    }
    return Run(system=system.name, settings=plan.settings, t=raw["t"].copy(), state=state, energy=energy,
               violation=violation, summary=summary)


# --------------------------------------------------------------------------- catalog
def catalog() -> dict:
    """Systems with parameters, variants, constraint names, integrators, limits (for /api/systems)."""
    from .integrators import INTEGRATORS
    from .registry import system_names

    out = []
    for name in system_names():
        s = get_system(name)
        out.append({
            "name": s.name, "title": s.title, "description": s.description,
            "option": s.option, s.option + "s": list(s.variants), "default_" + s.option: s.default_variant,
            "parameters": [{"name": p.name, "default": p.default, "min": p.min, "max": p.max,
                            "min_inclusive": p.min_inclusive, "unit": p.unit, "description": p.description}
                           for p in s.parameters],
            "coordinates": list(s.coordinates), "speeds": list(s.speeds),
            "independent": list(s.independent), "default_initial": dict(s.default_initial),
            "constraint_names": {v: list(s.constraint_names(v)) for v in s.variants},
            "defaults": {"dt": s.default_dt, "t_final": s.default_t_final,
                         "integrator": s.default_integrator, "gamma": s.default_gamma,
                         "gamma1": s.default_gamma1, "gamma2": s.default_gamma2},
        })
    return {"systems": out,
            "integrators": {k: v.description for k, v in INTEGRATORS.items()},
            "projections": ["none"],
            "limits": dict(LIMITS)}
