"""The physical forces a system declares (:mod:`nmkane_core.declare.forces`), on every row of a run.

:func:`add_point_forces` evaluates a variant's compiled point forces
(:func:`nmkane_core.kernel.forces.compile_forces`) on the rows of a finished run, from what
the run already holds — the state, λ (``Run.multipliers``) and F_c (``Run.constraint_forces``)
— and, for the forces whose route needs them (Newton's law: a mass centre's acceleration),
the rates q̇, u̇ of each row: the run's own right-hand side at that row (with the run's
gains, so the Baumgarte terms are in, as they are in F_c) — the loops' own ẋ of the row when
the driver keeps it (``LoopOutput.XD``, rows × 2N: the first stage of the step from the row
computes it), else the kernel's ``rhs_ws`` called row by row (about one right-hand side per
output row: what these forces cost).  The result is
``Run.point_forces`` (``NAME.LABEL`` → array) and ``summary["max_abs_point_force"]`` (the
largest |R| of each force).

Rows computed with an equivalent model (a run that switched near a singular configuration)
have no multipliers of the chosen model (they are reported as 0): there the forces are
those that model declares, with its λ recomputed from the row's F_c (least squares on its
Jacobian J: F_c = Jᵀλ) — the same physical force, written in its constraints.

:func:`point_forces_at` does the same at one state, for
:func:`nmkane_core.analysis.at_state.accelerations`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..kernel.built import built
from ..kernel.forces import CompiledForces, compile_forces

__all__ = ["add_point_forces", "point_forces_at", "rates_rows"]


def rates_rows(module, p, G, G1, G2, t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """ẋ = [q̇; u̇] of every row (n, 2N): the kernel's right-hand side, row by row."""
    n = x.shape[0]
    K = np.empty((n, x.shape[1]))
    fn = getattr(module, "rates_rows", None)  # a compiled loop over the rows, when the kernel has one
    if fn is not None:
        fn(t, x, p, G, G1, G2, K)
        return K
    w = module.make_workspace()
    xs = np.ascontiguousarray(x)
    for r in range(n):
        module.rhs_ws(float(t[r]), xs[r], p, G, G1, G2, K, r, w)
    return K


def _evaluate(compiled: CompiledForces, info, states, params, t, lam, fc, xdot) -> dict[str, np.ndarray]:
    rates = {}
    if compiled.rates:
        names = tuple(info.q) + tuple(info.u)
        rates = {k: xdot[:, names.index(k)] for k in compiled.rates}
    return compiled.components(
        states,
        params,
        {k: lam[k] for k in compiled.multipliers},
        {k: fc[k] for k in compiled.generalized},
        rates,
        t,
    )


def add_point_forces(plan, run, out) -> list[str]:
    """Set ``run.point_forces`` and ``run.summary["max_abs_point_force"]`` (a run with its
    constraint forces; ``plan``: its :class:`~nmkane_core.run.plan.Plan`, ``out``: the driver's
    :class:`~nmkane_core.integrate.job.LoopOutput`); returns warnings for the summary."""
    run.point_forces = {}
    if not plan.forces or not run.constraint_forces or run.t.size == 0:
        return []
    compiled = compile_forces(plan.system, plan.variant)
    if compiled is None:
        return []
    b = built(plan.system)
    info = b.info(plan.variant)
    xdot = None
    if compiled.rates:
        x = _state_rows(run, info)
        kept = getattr(out, "XD", None)  # ẋ of each row, when the loops keep it (they compute it: K[0])
        if kept is not None and kept.shape == x.shape:
            xdot = kept
        else:
            xdot = rates_rows(b.module(plan.variant), plan.p, plan.G, plan.G1, plan.G2, run.t, x)
    comps = _evaluate(compiled, info, run.state, plan.params, run.t, run.multipliers, run.constraint_forces, xdot)
    notes = _switched_rows(plan, run, out, compiled, comps)
    notes += _finite(run.t, comps)
    run.point_forces = comps
    run.summary["max_abs_point_force"] = {
        k: float(np.max(v, initial=0.0)) for k, v in compiled.magnitudes(comps).items()
    }
    return notes


def _state_rows(run, info) -> np.ndarray:
    """The run's state as rows (n, 2N), in the kernel's order."""
    return np.column_stack([run.state[k] for k in info.state_names])


def _switched_rows(plan, run, out, home: CompiledForces, comps: dict) -> list[str]:
    """Rows computed with an equivalent model: that model's declared forces, its λ from F_c."""
    ranges = list(getattr(out, "unknown_multipliers", []) or [])
    if not ranges:
        return []
    b = built(plan.system)
    x = _state_rows(run, b.info(plan.variant))
    leaving = [s for s in out.switches if s["from"] == plan.variant]
    notes = []
    for (t_a, t_b), sw in zip(ranges, leaving, strict=False):
        rows = np.flatnonzero((run.t >= t_a) & (run.t <= t_b))
        if rows.size == 0:
            continue
        variant = sw["to"]
        other = compile_forces(plan.system, variant)
        missing = [c for c in home.columns if other is None or c not in other.columns]
        if other is not None:
            info = b.info(variant)
            module = b.module(variant)
            p = b.param_vector(variant, plan.params)
            xr = np.ascontiguousarray(x[rows])
            tr = run.t[rows]
            fc = {k: run.constraint_forces[k][rows] for k in info.u}
            F = np.column_stack([fc[k] for k in info.u])
            lam = np.zeros((rows.size, info.m))
            for i in range(rows.size):
                J = module.state_terms(float(tr[i]), xr[i], p)[0]
                lam[i] = np.linalg.lstsq(J.T, F[i], rcond=None)[0]
            G, G1, G2 = _gains_for(plan, info)
            xdot = rates_rows(module, p, G, G1, G2, tr, xr) if other.rates else None
            states = {k: v[rows] for k, v in run.state.items()}
            lam_d = {k: lam[:, i] for i, k in enumerate(info.constraint_names)}
            sub = _evaluate(other, info, states, plan.params, tr, lam_d, fc, xdot)
            for c in home.columns:
                if c in sub:
                    comps[c][rows] = sub[c]
        for c in missing:
            comps[c][rows] = 0.0
        if missing:
            notes.append(
                f"point forces {', '.join(missing)} from t = {t_a:.6g} s to {t_b:.6g} s are reported as 0: the "
                f"{variant} model that ran there does not declare them"
            )
    return notes


def _gains_for(plan, info):
    """The run's gains when their shapes fit another variant, else zeros of its shapes."""
    m_nh, m_h = len(info.nonholonomic), len(info.holonomic)
    if plan.G.shape == (m_nh, m_nh) and plan.G1.shape == (m_h, m_h):
        return plan.G, plan.G1, plan.G2
    return np.zeros((m_nh, m_nh)), np.zeros((m_h, m_h)), np.zeros((m_h, m_h))


def _finite(t: np.ndarray, comps: dict) -> list[str]:
    """Components that are not finite (a singular constraint matrix) are reported as 0, with a warning."""
    finite = [np.isfinite(v) for v in comps.values()]
    if all(f.all() for f in finite):  # (none at all too)
        return []
    bad = ~np.all(finite, axis=0)
    for v in comps.values():
        v[bad] = 0.0
    times = t[bad]
    return [
        f"point forces are not defined at {int(bad.sum())} output row(s) (t = {times[0]:.6g}"
        + (f" … {times[-1]:.6g}" if times.size > 1 else "")
        + " s); reported as 0 there"
    ]


def point_forces_at(
    system,
    variant: str,
    t: float,
    state: Mapping[str, float],
    params: Mapping[str, float],
    multipliers: Mapping[str, float],
    generalized: Mapping[str, float],
    xdot: np.ndarray,
) -> dict[str, float]:
    """The declared point forces at one state (``NAME.LABEL`` → value; empty when none are
    declared): ``xdot`` = [q̇; u̇] there, ``multipliers``/``generalized``: λ and F_c there."""
    compiled = compile_forces(system, variant)
    if compiled is None:
        return {}
    info = built(system).info(variant)
    one = {k: np.array([float(v)]) for k, v in state.items()}
    lam = {k: np.array([float(v)]) for k, v in multipliers.items()}
    fc = {k: np.array([float(v)]) for k, v in generalized.items()}
    comps = _evaluate(compiled, info, one, dict(params), np.array([float(t)]), lam, fc, np.asarray(xdot)[None, :])
    return {k: float(v[0]) for k, v in comps.items()}
