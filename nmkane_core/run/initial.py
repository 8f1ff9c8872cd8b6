"""Consistent initial states: complete from independent values, or check a full state.

Given values for the *independent* coordinates and speeds (the rest taken from the
system's defaults), the dependent ones are solved from the constraints by Newton's
method with the compiled kernel's Jacobians: first the holonomic ψ(q) = 0 for the
dependent coordinates, then the velocity constraints [φ; ψ̇] = 0 for u_D.  A system may
name a ``completion_variant`` (the Appell–Hamel mechanism uses its linear model, whose
velocity constraints have one solution) — the state is then checked against the chosen
variant's own constraints.  A full state (every name given) is not changed, only checked.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import ConvergenceError, InconsistentStateError, InputError

if TYPE_CHECKING:
    from ..declare.system import System

__all__ = ["initial_state", "CHECK_TOL"]

#: absolute tolerance on each constraint residual of a given full state
CHECK_TOL = 1e-8


def _newton(residual, x, idx, label, names, tol=1e-13, maxit=60):
    """Solve residual(x)[0] = 0 for x[idx]; residual returns (r, dr/dx[idx]); ``names`` name
    the rows of r (for messages).

    Damped: a step that does not decrease |r| (or leaves the domain where r is finite — a
    square root of a negative number) is halved until it does.  When the guess sits where the
    Jacobian is singular (a zero guess for u1 in √(u1² + u2²) − v), Newton is restarted from
    a small nonzero guess: first positive, then negative (a zero guess picks the positive
    branch).  Raises :class:`ConvergenceError` naming the constraints left unsatisfied.
    """
    errors = []
    for start in _starts(x, idx):
        try:
            return _damped_newton(residual, start, idx, label, names, tol, maxit)
        except ConvergenceError as e:
            errors.append(e)
    raise errors[0]


def _starts(x, idx):
    """The given guess, then (if some unknowns are 0 there) the same with those set to ±δ."""
    yield x
    zero = [i for i in idx if x[i] == 0.0]
    if zero:
        delta = 0.1 * max(1.0, float(np.abs(x).max(initial=0.0)))
        for sign in (1.0, -1.0):
            y = x.copy()
            y[zero] = sign * delta
            yield y


def _damped_newton(residual, x, idx, label, names, tol, maxit):
    x = x.copy()
    r, jac = residual(x)
    norm = float(np.abs(r).max(initial=0.0))
    for _ in range(maxit):
        if not np.isfinite(norm):
            raise ConvergenceError(
                f"{label}: the constraints are not defined at the starting guess ({_report(names, r)})"
            )
        if norm <= tol * (1.0 + np.abs(x[idx]).max(initial=0.0)):
            return x
        try:
            step = np.linalg.solve(jac, r)
        except np.linalg.LinAlgError:
            step = None
        if step is None or not np.all(np.isfinite(step)):
            raise ConvergenceError(
                f"{label}: the constraint Jacobian is singular at {_at(x, idx)} ({_report(names, r)})"
            )
        lam = 1.0
        for _ in range(40):  # backtracking: accept the first step that decreases |r|
            y = x.copy()
            y[idx] -= lam * step
            ry, jy = residual(y)
            ny = float(np.abs(ry).max(initial=0.0))
            if np.isfinite(ny) and ny < norm:
                break
            lam *= 0.5
        else:
            raise ConvergenceError(
                f"{label}: no step decreases the residual ({_report(names, r)}) — "
                f"the constraints seem to have no solution near the guess"
            )
        x, r, jac, norm = y, ry, jy, ny
    raise ConvergenceError(f"{label}: Newton did not converge in {maxit} iterations ({_report(names, r)})")


def _report(names, r) -> str:
    return "residual " + ", ".join(f"{k} = {v:.3g}" for k, v in zip(names, r, strict=True))


def _at(x, idx) -> str:
    return "the guess (" + ", ".join(f"{x[i]:.6g}" for i in idx) + ")"


def complete_state(module, info, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Solve the dependent coordinates and speeds of ``x`` (model order) from the constraints.

    ``module`` is the compiled kernel, ``info`` its :class:`~nmkane_core.kernel.info.ModelInfo`, ``x`` the
    state with the independent values set and the dependent ones holding starting guesses (which
    pick the branch of a constraint nonlinear in the speeds), ``p`` the parameter vector.
    Raises :class:`ConvergenceError` (naming the constraints left unsatisfied) when Newton fails.
    """
    n = info.n
    if info.holonomic:
        qi = [info.q.index(s) for s in info.q_dependent]

        def holo(z):
            _, _, psi, psi_q, _ = module.state_terms(0.0, z, p)
            return psi, psi_q[:, qi]

        x = _newton(
            holo, x, qi, f"holonomic constraints ψ(q) = 0 solved for {', '.join(info.q_dependent)}", info.holonomic
        )
    if info.m:
        ud = [s for s in info.u if s not in info.u_independent]
        ui = [n + info.u.index(s) for s in ud]

        def vel(z):
            J, c, _, _, _ = module.state_terms(0.0, z, p)
            return c, J[:, [i - n for i in ui]]

        x = _newton(
            vel,
            x,
            ui,
            f"velocity constraints [φ; ψ̇] = 0 solved for {', '.join(ud)}",
            info.nonholonomic + tuple(f"d/dt {h}" for h in info.holonomic),
        )
    return x


def project_onto_manifold(module, info, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The nearest consistent state (Euclidean metric): positions onto ψ = 0, then speeds onto
    [φ; ψ̇] = 0 at the corrected positions (the kernel's post-step projection, iterated)."""
    from ..integrate.projection import ProjectionOptions

    proj = ProjectionOptions(
        "onto-manifold", weight="identity", iterations=20, jacobian="updated", energy=False
    ).as_array(info)
    y, code = module.project_state(0.0, x, p, proj)
    if code != 0 or not np.all(np.isfinite(y)):
        raise ConvergenceError("the projection onto the constraint manifold met a singular matrix")
    return y


def initial_state(
    system: System,
    variant: str,
    params: dict[str, float],
    given: dict[str, float],
    project: bool = False,
    correction: dict | None = None,
    complete_always: bool = False,
) -> tuple[np.ndarray, dict[str, float]]:
    """The variant model's initial state vector and the full state (by name).

    Raises :class:`InputError` for unknown names, :class:`InconsistentStateError` when a
    full state violates the constraints by more than :data:`CHECK_TOL` — unless
    ``project`` is set: then the state is projected onto the constraint manifold of the
    completion variant and the change is written into ``correction``.  The system's
    default state is taken as consistent (it was checked when the system was registered)
    unless ``complete_always``: then dependent values missing from it are completed too.
    """
    names = system.state_names
    for k, v in given.items():
        if k not in names:
            raise InputError(
                f"initial.{k}", v, f"state names of {system.name}: {', '.join(names)}", "unknown state name"
            )
        if not np.isfinite(v):
            raise InputError(f"initial.{k}", v, "a finite number", "not finite")
    full = dict(system.default_initial)
    full.update(given)
    dependent = [k for k in names if k not in system.independent]
    given_dep = [k for k in dependent if k in given]
    if given_dep and len(given) < len(names):
        missing = [k for k in names if k not in given]
        raise InputError(
            f"initial.{given_dep[0]}",
            given[given_dep[0]],
            f"either independent values only ({', '.join(system.independent)}), "
            f"the rest being completed, or a full state (missing: {', '.join(missing)})",
            "dependent value given without a full state",
        )
    # the default state is consistent for the default parameters; anything else given
    # without dependent values is completed
    defaults = all(params[q.name] == q.default for q in system.parameters)
    complete = not given_dep and (bool(given) or not defaults or complete_always or any(k not in full for k in names))
    comp_variant = system.completion_variant or variant
    p = system.param_vector(comp_variant, params)
    if complete:
        module, info = system.kernel(comp_variant)
        xc = np.array([full.get(s, 0.0) for s in info.state_names], float)
        try:
            xc = complete_state(module, info, xc, p)
        except ConvergenceError as e:
            dep = [k for k in names if k not in system.independent]
            raise InputError(
                "initial",
                given,
                f"independent values ({', '.join(system.independent)}) for which the constraints can be "
                f"solved for the dependent ones ({', '.join(dep)}) with the parameters given — change them, "
                f"or give a full consistent state; the system's default_initial holds the starting "
                f"guesses of the dependent values (they pick the branch)",
                str(e),
            ) from None
        for s, v in zip(info.state_names, xc, strict=True):
            full[s] = float(v)
    # check against the chosen variant, and against the completion variant for states
    # that were completed or given in full (it may exclude branches the variant admits)
    if project and given_dep:
        module, info = system.kernel(comp_variant)
        xc = np.array([full[s] for s in info.state_names], float)
        try:
            y = project_onto_manifold(module, info, xc, p)
        except ConvergenceError as e:
            raise InputError("initial", given, "a state that can be projected onto the constraints", str(e)) from None
        for s, a, b in zip(info.state_names, xc, y, strict=True):
            full[s] = float(b)
            if correction is not None and a != b:
                correction[s] = float(b - a)
    checks = [variant] + ([comp_variant] if (complete or given_dep) else [])
    failed = {}
    for var in dict.fromkeys(checks):
        module, info = system.kernel(var)
        p = system.param_vector(var, params)
        if any(s not in full for s in info.state_names):
            continue
        xv = np.array([full[s] for s in info.state_names], float)
        viol = module.state_terms(0.0, xv, p)[4][: info.m]
        bad = {name: float(val) for name, val in zip(info.constraint_names, viol, strict=True) if abs(val) > CHECK_TOL}
        if bad:
            failed[var] = ", ".join(f"{k} = {v:.3g}" for k, v in bad.items())
    if failed:
        if variant not in failed:
            other = next(iter(failed))
            reason = (
                f"the state satisfies the constraints of the {variant} {system.option} but not those "
                f"of the {other} {system.option} ({failed[other]}): it lies on a spurious branch of "
                f"the {variant} constraints that the mechanism excludes"
            )
        else:
            reason = "constraint residuals " + "; ".join(f"{v} {system.option}: {d}" for v, d in failed.items())
        raise InconsistentStateError(
            "initial",
            {k: full[k] for k in names},
            f"a state satisfying the constraints of the {' and '.join(dict.fromkeys(checks))} "
            f"{system.option} within {CHECK_TOL:g}",
            reason,
        )
    info = system.info(variant)
    x0 = np.array([full[s] for s in info.state_names], float)
    return x0, {k: float(full[k]) for k in names}
