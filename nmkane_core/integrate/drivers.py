"""The loop drivers: a :class:`~nmkane_core.run.plan.Plan` integrated in chunks of compiled work.

:func:`run_fixed` and :func:`run_adaptive` call the compiled loops (arguments
:class:`~nmkane_core.kernel.interface.FixedArgs`, :class:`~nmkane_core.kernel.interface.AdaptiveArgs`) chunk by
chunk, :func:`run_scipy` steps a scipy solver; between chunks each updates the progress bar,
checks the time limit and cancellation, and lets the :class:`~nmkane_core.integrate.switching.Switcher`
change the model near a singular configuration.  Each returns a
:class:`~nmkane_core.run.result.LoopOutput` that keeps everything computed up to the last good step.
:func:`prepare` loads (or compiles) what a run needs before its clock starts.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..declare.system import System
from ..kernel.built import built
from ..kernel.interface import (
    STATS_E0,
    STATS_FINAL_DRIFT,
    STATS_MAX_DRIFT,
    STATS_RCOND_J2,
    STATS_RCOND_T,
    STATS_VIOL,
    STATUS_BUDGET,
    STATUS_DIVERGED,
    STATUS_FAILED,
    STATUS_J2_SINGULAR,
    STATUS_OK,
    STATUS_T_SINGULAR,
    AdaptiveArgs,
    FixedArgs,
)
from ..run.plan import Plan
from ..run.result import LoopOutput
from ..schema import LIMITS
from .methods import ScipyMethod, Tableau
from .switching import Switcher

__all__ = [
    "kernel_for",
    "prepare",
    "run_fixed",
    "run_adaptive",
    "run_scipy",
    "FIXED_FIRST_CHUNK",
    "ADAPTIVE_ROWS_PER_CALL",
    "ADAPTIVE_ATTEMPTS_PER_CALL",
    "SCIPY_STEPS_PER_CHECK",
]

FIXED_FIRST_CHUNK = 2000  # steps of the first fixed-step call; later calls aim at ~50 ms each
FIXED_CHUNK_SECONDS = 0.05
FIXED_MIN_CHUNK, FIXED_MAX_CHUNK = 500, 5_000_000
ADAPTIVE_ROWS_PER_CALL = 4096  # output buffer of one adaptive call: the most rows a call adds
ADAPTIVE_ATTEMPTS_PER_CALL = 200_000
SCIPY_STEPS_PER_CHECK = 200  # the scipy adapter checks time limit and cancellation this often
HMIN_REL = 1e-13  # adaptive runs fail below a step of HMIN_REL · max(1, t_final)


def kernel_for(system: System, variant: str):
    """The compiled kernel module of a system's variant (loaded from cache or built once)."""
    return built(system).module(variant)


def prepare(plan: Plan):
    """Load — or, on a model's first use, compile — everything ``simulate(plan)`` runs, so
    that the run itself starts at once (the CLI does this under a "first use" notice): the
    selected variant's kernel and loop and, when the run may switch models, those of every
    equivalent variant it may switch to.  Returns the kernel module of the selected variant."""
    mod = kernel_for(plan.system, plan.variant)
    _prime(plan, mod, plan.p)
    if plan.switching:
        for variant in plan.system.equivalents.get(plan.variant, ()):
            _prime(plan, kernel_for(plan.system, variant), built(plan.system).param_vector(variant, plan.params))
    return mod


def _prime(plan: Plan, mod, p: np.ndarray) -> None:
    """Call the run's compiled loop (with the kernel module ``mod`` and its parameter vector
    ``p``) once with no work, so that a first run compiles (or loads from the disk cache)
    before its clock starts: ``time_limit`` bounds integration, not compilation, and the
    time shows as ``kernel_load_s``.  The helpers a driver calls around the loop (initial
    diagnostics, the conditioning check of a model switch) are called once too.  Argument
    types are exactly those of the real calls below (numba compiles one copy per type signature)."""
    from ..kernel import precompile

    precompile.wait(mod)  # a new kernel's loop may be compiling next door
    tab = plan.integrator
    n2 = plan.x0.size
    mod.diagnostics_rows(np.zeros(1), plan.x0[None, :].copy(), p, np.empty(1), np.empty((1, mod.NV)))
    if isinstance(tab, ScipyMethod):  # scipy calls the right-hand side and diagnostics
        mod.rhs_ws(0.0, plan.x0.copy(), p, plan.G, plan.G1, plan.G2, np.empty((1, n2)), 0, mod.make_workspace())
        mod.diagnostics(0.0, plan.x0.copy(), p, np.empty(mod.NV))
        return
    mod.rhs(0.0, plan.x0.copy(), p, plan.G, plan.G1, plan.G2)  # the switcher's conditioning check
    x = plan.x0.copy()
    out_t, out_x = np.empty(1), np.empty((1, n2))
    out_E, out_V = np.empty(1), np.empty((1, mod.NV))
    stats = np.zeros(STATS_VIOL + mod.NV)
    proj = plan.projection.as_array(plan.info)
    if tab.adaptive:
        assert tab.E is not None
        mod.integrate_adaptive(
            *AdaptiveArgs(
                x,
                0.0,
                plan.t_final,
                h=0.1,
                rtol=plan.rtol,
                atol=plan.atol,
                hmin=1e-13,
                hmax=1.0,
                max_steps=0,
                every=1,
                accepted=0,
                p=p,
                G=plan.G,
                G1=plan.G1,
                G2=plan.G2,
                TA=tab.A,
                TB=tab.b,
                TE=tab.E,
                TC=tab.c,
                err_exp=0.2,
                rcond_min=0.0,
                proj=proj,
                out_t=out_t,
                out_x=out_x,
                out_E=out_E,
                out_V=out_V,
                stats=stats,
            )
        )
    else:
        mod.integrate_fixed(
            *FixedArgs(
                x,
                0.0,
                plan.dt,
                plan.t_final,
                k0=0,
                k1=0,
                nsteps=1,
                every=1,
                p=p,
                G=plan.G,
                G1=plan.G1,
                G2=plan.G2,
                TA=tab.A,
                TB=tab.b,
                TC=tab.c,
                rcond_min=0.0,
                proj=proj,
                out_t=out_t,
                out_x=out_x,
                out_E=out_E,
                out_V=out_V,
                row=0,
                stats=stats,
            )
        )


def _stats0(plan, mod):
    """The ``stats`` array at the initial state, and its energy and violations."""
    nv = mod.NV
    E0 = np.empty(1)
    V0 = np.empty((1, nv))
    mod.diagnostics_rows(np.zeros(1), plan.x0[None, :], plan.p, E0, V0)
    stats = np.zeros(STATS_VIOL + nv)
    stats[STATS_E0] = E0[0]
    stats[STATS_RCOND_J2] = stats[STATS_RCOND_T] = 1.0
    stats[STATS_VIOL:] = np.abs(V0[0])
    return stats, E0[0], V0[0]


def _interrupted(start, time_limit, cancel):
    if cancel is not None and cancel():
        return "cancelled"
    if time_limit is not None and time.perf_counter() - start > time_limit:
        return "timeout"
    return None


def _singular(status) -> bool:
    return status in (STATUS_J2_SINGULAR, STATUS_T_SINGULAR)


def run_fixed(plan: Plan, mod, bar, start, time_limit, cancel) -> LoopOutput:
    tab = plan.integrator
    assert isinstance(tab, Tableau)
    dt, t_final, every = plan.dt, plan.t_final, plan.every
    nsteps = max(1, math.ceil(t_final / dt - 1e-9))
    rows = nsteps // every + (1 if nsteps % every else 0) + 2
    n2 = plan.x0.size
    out_t, out_x = np.empty(rows), np.empty((rows, n2))
    out_E, out_V = np.empty(rows), np.empty((rows, mod.NV))
    stats, E0, V0 = _stats0(plan, mod)
    out_t[0], out_x[0], out_E[0], out_V[0] = 0.0, plan.x0, E0, V0
    x = plan.x0.copy()
    row, k, status, stop = 1, 0, STATUS_OK, None
    chunk = FIXED_FIRST_CHUNK
    sw = Switcher(plan, mod)
    args = FixedArgs(
        x,
        0.0,
        dt,
        t_final,
        k0=0,
        k1=0,
        nsteps=nsteps,
        every=every,
        p=plan.p,
        G=plan.G,
        G1=plan.G1,
        G2=plan.G2,
        TA=tab.A,
        TB=tab.b,
        TC=tab.c,
        rcond_min=0.0,
        proj=plan.projection.as_array(plan.info),  # None without projection (see the loops)
        out_t=out_t,
        out_x=out_x,
        out_E=out_E,
        out_V=out_V,
        row=row,
        stats=stats,
    )
    while k < nsteps:
        t_call = time.perf_counter()
        k_end = min(nsteps, k + (sw.SWITCHED_CHUNK if sw.switched else chunk))
        status, k, row = sw.cur.integrate_fixed(*args._replace(k0=k, k1=k_end, rcond_min=sw.threshold, row=row, p=sw.p))
        elapsed = time.perf_counter() - t_call
        if not sw.switched:
            chunk = int(
                min(max(chunk * min(4.0, FIXED_CHUNK_SECONDS / max(elapsed, 1e-6)), FIXED_MIN_CHUNK), FIXED_MAX_CHUNK)
            )
        bar.update(min(k * dt, t_final))
        if _singular(status) and sw.leave(k * dt, x, row):
            status = STATUS_OK
            continue
        if status != STATUS_OK:
            break
        sw.maybe_return(k * dt, x, row)
        stop = _interrupted(start, time_limit, cancel)
        if stop and k < nsteps:
            break
    t_last = t_final if k >= nsteps and status == STATUS_OK else k * dt
    if row == 0 or out_t[row - 1] < t_last - 1e-12 * max(1.0, t_last):
        # keep the last good state even when thinning skipped it
        out_t[row], out_x[row] = t_last, x
        mod.diagnostics_rows(
            out_t[row : row + 1], out_x[row : row + 1], plan.p, out_E[row : row + 1], out_V[row : row + 1]
        )
        row += 1
    sw.finish(row, out_t, out_x, out_E, out_V, stats)
    return LoopOutput(
        status=status,
        stop=stop,
        t=out_t[:row],
        x=out_x[:row],
        E=out_E[:row],
        V=out_V[:row],
        stats=stats,
        steps=k,
        evals=k * tab.stages,
        t_end=t_last,
        switches=sw.switches,
    )


def run_adaptive(plan: Plan, mod, bar, start, time_limit, cancel) -> LoopOutput:
    tab = plan.integrator
    assert isinstance(tab, Tableau) and tab.E is not None and tab.error_order is not None
    t_final = plan.t_final
    n2 = plan.x0.size
    stats, E0, V0 = _stats0(plan, mod)
    ts, xs, Es, Vs = [np.zeros(1)], [plan.x0[None, :].copy()], [np.array([E0])], [V0[None, :].copy()]
    x = plan.x0.copy()
    t, h = 0.0, min(plan.dt, t_final)
    accepted = attempts = 0
    status, stop = STATUS_OK, None
    hmin = HMIN_REL * max(1.0, t_final)
    err_exp = 1.0 / (tab.error_order + 1)
    sw = Switcher(plan, mod)
    proj = plan.projection.as_array(plan.info)  # None without projection (see the loops)
    nrows = 1
    while t < t_final:
        size = sw.SWITCHED_CHUNK if sw.switched else ADAPTIVE_ROWS_PER_CALL
        out_t, out_x = np.empty(size), np.empty((size, n2))
        out_E, out_V = np.empty(size), np.empty((size, mod.NV))
        budget = int(
            min(sw.SWITCHED_CHUNK if sw.switched else ADAPTIVE_ATTEMPTS_PER_CALL, LIMITS["max_steps"] - attempts)
        )
        status, t, h, nrow, accepted, att = sw.cur.integrate_adaptive(
            *AdaptiveArgs(
                x,
                t,
                t_final,
                h,
                plan.rtol,
                plan.atol,
                hmin,
                hmax=t_final,
                max_steps=budget,
                every=plan.every,
                accepted=accepted,
                p=sw.p,
                G=plan.G,
                G1=plan.G1,
                G2=plan.G2,
                TA=tab.A,
                TB=tab.b,
                TE=tab.E,
                TC=tab.c,
                err_exp=err_exp,
                rcond_min=sw.threshold,
                proj=proj,
                out_t=out_t,
                out_x=out_x,
                out_E=out_E,
                out_V=out_V,
                stats=stats,
            )
        )
        attempts += att
        ts.append(out_t[:nrow])
        xs.append(out_x[:nrow])
        Es.append(out_E[:nrow])
        Vs.append(out_V[:nrow])
        nrows += nrow
        bar.update(t)
        if nrows >= LIMITS["max_rows"] and t < t_final:
            status, stop = STATUS_FAILED, "max_rows"  # output bounded: a step size collapsing
            break  # toward a singularity cannot fill memory
        if _singular(status) and sw.leave(t, x, nrows):
            status = STATUS_OK
            continue
        if status == STATUS_BUDGET:
            status = STATUS_OK
            if attempts >= LIMITS["max_steps"]:
                status = STATUS_FAILED
                stop = "max_steps"
                break
        if status != STATUS_OK:
            break
        sw.maybe_return(t, x, nrows)
        stop = _interrupted(start, time_limit, cancel)
        if stop and t < t_final:
            break
        stop = None
    if np.concatenate(ts)[-1] < t - 1e-12 * max(1.0, t):
        ts.append(np.array([t]))
        xs.append(x[None, :].copy())
        E, V = np.empty(1), np.empty((1, mod.NV))
        mod.diagnostics_rows(ts[-1], xs[-1], plan.p, E, V)
        Es.append(E)
        Vs.append(V)
        nrows += 1
    t_arr, x_arr, E_arr, V_arr = (np.concatenate(a) for a in (ts, xs, Es, Vs))
    sw.finish(nrows, t_arr, x_arr, E_arr, V_arr, stats)
    return LoopOutput(
        status=status,
        stop=stop,
        t=t_arr,
        x=x_arr,
        E=E_arr,
        V=V_arr,
        stats=stats,
        steps=accepted,
        evals=attempts * tab.stages,
        t_end=t,
        switches=sw.switches,
    )


class _NonFinite(ArithmeticError):
    """The right-hand side is not finite at a state a scipy solver asked for."""


def run_scipy(plan: Plan, mod, bar, start, time_limit, cancel) -> LoopOutput:
    import scipy.integrate as si

    assert isinstance(plan.integrator, ScipyMethod)

    from ..errors import SingularMatrix

    w = mod.make_workspace()
    n2 = plan.x0.size
    K = np.empty((1, n2))
    rcmin = [1.0, 1.0]

    def fun(t, x):
        mod.rhs_ws(t, np.ascontiguousarray(x, dtype=float), plan.p, plan.G, plan.G1, plan.G2, K, 0, w)
        rc0, rc1 = w[mod.ORC], w[mod.ORC + 1]
        if not (np.all(np.isfinite(w[: mod.ORC])) and np.all(np.isfinite(K[0]))):
            # the model's expressions are not defined here (√ of a negative number, a zero denominator):
            # the run ends "diverged" at the last accepted step.  (Returning NaN would let an explicit
            # solver reject and shrink the step, but it can then creep on along the edge of the domain
            # with ever smaller steps, off the constraint; radau's LU would raise.)
            raise _NonFinite(t)
        rcmin[0], rcmin[1] = min(rcmin[0], rc0), min(rcmin[1], rc1)
        if rc0 <= plan.rcond_min:
            raise SingularMatrix("J2", rc0, t)
        if rc1 <= plan.rcond_min:
            raise SingularMatrix("T", rc1, t)
        return K[0].copy()

    stats, _E0, _V0 = _stats0(plan, mod)
    ts, xs = [0.0], [plan.x0.copy()]
    status, stop, nstep = STATUS_OK, None, 0
    viol = np.empty(mod.NV)
    fail_msg = None
    try:
        solver = getattr(si, plan.integrator.solver)(
            fun,
            0.0,
            plan.x0.copy(),
            plan.t_final,
            rtol=plan.rtol,
            atol=plan.atol,
            first_step=min(plan.dt, plan.t_final),
        )
        while solver.status == "running":
            msg = solver.step()
            if solver.status == "failed":
                status, fail_msg = STATUS_FAILED, msg
                break
            y = solver.y
            if not np.all(np.isfinite(y)):
                status = STATUS_DIVERGED
                break
            nstep += 1
            E = mod.diagnostics(solver.t, y, plan.p, viol)
            if not (math.isfinite(E) and np.all(np.isfinite(viol))):
                status = STATUS_DIVERGED
                break
            stats[STATS_MAX_DRIFT] = max(stats[STATS_MAX_DRIFT], abs(E - stats[STATS_E0]))
            stats[STATS_FINAL_DRIFT] = E - stats[STATS_E0]
            stats[STATS_VIOL:] = np.maximum(stats[STATS_VIOL:], np.abs(viol))
            if nstep % plan.every == 0 or solver.status == "finished":
                ts.append(solver.t)
                xs.append(y.copy())
                if len(ts) >= LIMITS["max_rows"] and solver.status == "running":
                    status, stop = STATUS_FAILED, "max_rows"
                    break
            if nstep >= LIMITS["max_steps"]:
                status, stop = STATUS_FAILED, "max_steps"
                break
            if nstep % SCIPY_STEPS_PER_CHECK == 0:
                bar.update(solver.t)
                stop = _interrupted(start, time_limit, cancel)
                if stop:
                    break
        nfev = solver.nfev
    except SingularMatrix as e:
        status = STATUS_J2_SINGULAR if e.matrix == "J2" else STATUS_T_SINGULAR
        nfev = 0
    except _NonFinite:
        status, nfev = STATUS_DIVERGED, 0
    except (ArithmeticError, ValueError, np.linalg.LinAlgError) as e:  # raised inside scipy's solver
        status, nfev = STATUS_FAILED, 0
        fail_msg = f"{plan.integrator.name} failed after t = {ts[-1]:.6g} s: {e}"
    stats[STATS_RCOND_J2], stats[STATS_RCOND_T] = rcmin
    t_arr, x_arr = np.array(ts), np.array(xs)
    E_arr, V_arr = np.empty(len(ts)), np.empty((len(ts), mod.NV))
    mod.diagnostics_rows(t_arr, x_arr, plan.p, E_arr, V_arr)
    return LoopOutput(
        status=status,
        stop=stop,
        t=t_arr,
        x=x_arr,
        E=E_arr,
        V=V_arr,
        stats=stats,
        steps=nstep,
        evals=nfev,
        t_end=float(t_arr[-1]),
        fail_msg=fail_msg,
    )
