"""Consistent initial states: complete from independent values, or check a full state.

Given values for the *independent* coordinates and speeds (the rest taken from the
system's defaults), the dependent ones are solved from the constraints by Newton's
method with the compiled kernel's Jacobians: first the holonomic ψ(q) = 0 for the
dependent coordinates, then the velocity constraints [φ; ψ̇] = 0 for u_D.  A system may
name a ``completion_variant`` (a mechanism with a constraint nonlinear in the speeds may use its linear model, whose
velocity constraints have one solution) — the state is then checked against the chosen
variant's own constraints.  A full state (every name given) is not changed, only checked.
"""

from __future__ import annotations

import threading
import weakref

import numpy as np

from ..declare.system import System
from ..errors import ConvergenceError, InconsistentStateError, InputError
from ..kernel.built import built
from .partition import max_rank, partition

__all__ = ["initial_state", "default_state", "complete_state", "CHECK_TOL"]

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
        step = _newton_step(jac, r)
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


def _newton_step(jac: np.ndarray, r: np.ndarray) -> np.ndarray | None:
    """The Newton step J⁻¹r; the least-squares, smallest step when J is not square or is
    singular (redundant equations: more constraints than unknowns, consistent on the manifold)."""
    if jac.shape[0] == jac.shape[1]:
        try:
            return np.linalg.solve(jac, r)
        except np.linalg.LinAlgError:
            pass
    if not (np.all(np.isfinite(jac)) and np.all(np.isfinite(r))):
        return None
    step, _, rank, _ = np.linalg.lstsq(jac, r, rcond=1e-10)
    return step if rank > 0 else None


def _report(names, r) -> str:
    return "residual " + ", ".join(f"{k} = {v:.3g}" for k, v in zip(names, r, strict=True))


def _at(x, idx) -> str:
    return "the guess (" + ", ".join(f"{x[i]:.6g}" for i in idx) + ")"


def complete_state(module, info, x: np.ndarray, p: np.ndarray, partition=None) -> np.ndarray:
    """Solve the dependent coordinates and speeds of ``x`` (model order) from the constraints.

    ``module`` is the compiled kernel, ``info`` its :class:`~nmkane_core.kernel.info.ModelInfo`, ``x`` the
    state with the independent values set and the dependent ones holding starting guesses (which
    pick the branch of a constraint nonlinear in the speeds), ``p`` the parameter vector;
    ``partition`` = (q_dependent, u_independent) when the model declares none
    (:mod:`nmkane_core.run.partition`).  Redundant equations are solved in the least-squares
    sense (consistent at a solution).
    Raises :class:`ConvergenceError` (naming the constraints left unsatisfied) when Newton fails.
    """
    n = info.n
    q_dep, u_ind = partition if partition is not None else (info.q_dependent, info.u_independent)
    if info.holonomic and q_dep:
        qi = [info.q.index(s) for s in q_dep]

        def holo(z):
            _, _, psi, psi_q, _ = module.state_terms(0.0, z, p)
            return psi, psi_q[:, qi]

        x = _newton(holo, x, qi, f"holonomic constraints ψ(q) = 0 solved for {', '.join(q_dep)}", info.holonomic)
    if info.m:
        ud = [s for s in info.u if s not in u_ind]
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


def project_onto_manifold(module, info, x: np.ndarray, p: np.ndarray, max_rank: int = 0) -> np.ndarray:
    """The nearest consistent state (Euclidean metric): positions onto ψ = 0, then speeds onto
    [φ; ψ̇] = 0 at the corrected positions (the kernel's post-step projection, iterated)."""
    from ..integrate.projection import ProjectionOptions

    proj = ProjectionOptions(
        "onto-manifold", weight="identity", iterations=20, jacobian="updated", energy=False
    ).as_array(info)
    if module.ROBUST and not module.DECLARED:  # no declared partition, or redundant equations
        y, code = module.project_state_robust(0.0, x, p, proj, max_rank)
    else:
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
) -> tuple[np.ndarray, dict[str, float]]:
    """The variant model's initial state vector and the full state (by name).

    ``given`` values replace the system's default state (:func:`default_state`); independent
    values alone are completed (the dependent ones solved from the constraints), a full state
    is only checked.  Raises :class:`InputError` for unknown names,
    :class:`InconsistentStateError` when a full state violates the constraints by more than
    :data:`CHECK_TOL` — unless ``project`` is set: then the state is projected onto the
    constraint manifold of the completion variant and the change is written into
    ``correction``.
    """
    return _state(system, variant, params, given, default_state(system), project, correction)


_DEFAULTS: dict[int, tuple[weakref.ref, dict[str, float]]] = {}
_DEFAULTS_LOCK = threading.Lock()


def default_state(system: System) -> dict[str, float]:
    """The system's default initial state as a full consistent state (by name): the declared
    ``default_initial`` — independent values, completed from the constraints (values given for
    dependent ones are the starting guesses that pick the branch), or a full state, checked —
    for the default parameters.  Computed once per system; the declaration is not changed.
    Raises :class:`InputError` naming ``default_initial`` when it cannot be completed."""
    with _DEFAULTS_LOCK:
        entry = _DEFAULTS.get(id(system))
        if entry is not None and entry[0]() is system:
            return dict(entry[1])
    b = built(system)
    for v in dict.fromkeys((system.completion_variant, system.default_variant)):
        partition(system, v)  # a model without a declared partition: picked before anything is completed
    names = b.state_names
    declared = dict(system.default_initial)
    for k, val in declared.items():
        if k not in names:
            raise InputError(
                f"{system.name}: default_initial.{k}",
                val,
                f"state names of {system.name}: {', '.join(names)}",
                "not a coordinate or speed",
            )
    independent = set(b.independent)
    given = declared if len(declared) == len(names) else {k: v for k, v in declared.items() if k in independent}
    try:
        _, full = _state(
            system, system.default_variant, system.resolve_params({}), given, declared, complete_always=True
        )
    except InputError as e:
        raise InputError(
            f"{system.name}: default_initial",
            declared,
            "independent values (the rest is completed) or a full consistent state",
            f"{e.field}: {e.reason or e.allowed}",
        ) from None
    with _DEFAULTS_LOCK:
        _DEFAULTS[id(system)] = (weakref.ref(system), dict(full))
    return full


def _state(
    system: System,
    variant: str,
    params: dict[str, float],
    given: dict[str, float],
    base: dict[str, float],
    project: bool = False,
    correction: dict | None = None,
    complete_always: bool = False,
) -> tuple[np.ndarray, dict[str, float]]:
    """:func:`initial_state` over the state ``base`` (the default state, or while that is
    made, the declared values; ``complete_always``: complete even at the default parameters)."""
    b = built(system)
    names = b.state_names
    _check_names(system, names, given)
    full = {**base, **given}
    given_dep = _given_dependent(b, names, given)
    # the default state is consistent for the default parameters; anything else given
    # without dependent values is completed
    defaults = all(params[q.name] == q.default for q in system.parameters)
    complete = not given_dep and (bool(given) or not defaults or complete_always or any(k not in full for k in names))
    comp_variant = system.completion_variant or variant
    if complete:
        _complete(system, comp_variant, params, given, full)
    if project and given_dep:
        _project(system, comp_variant, params, given, full, correction)
    _check_consistent(system, variant, params, full, [variant] + ([comp_variant] if (complete or given_dep) else []))
    x0 = np.array([full[s] for s in b.info(variant).state_names], float)
    return x0, {k: float(full[k]) for k in names}


def _check_names(system: System, names: tuple[str, ...], given: dict[str, float]) -> None:
    for k, v in given.items():
        if k not in names:
            raise InputError(
                f"initial.{k}", v, f"state names of {system.name}: {', '.join(names)}", "unknown state name"
            )
        if not np.isfinite(v):
            raise InputError(f"initial.{k}", v, "a finite number", "not finite")


def _given_dependent(b, names, given) -> list[str]:
    """The dependent values among ``given``: allowed only as part of a full state."""
    dependent = [k for k in names if k not in b.independent]
    given_dep = [k for k in dependent if k in given]
    if given_dep and len(given) < len(names):
        missing = [k for k in names if k not in given]
        raise InputError(
            f"initial.{given_dep[0]}",
            given[given_dep[0]],
            f"either independent values only ({', '.join(b.independent)}), "
            f"the rest being completed, or a full state (missing: {', '.join(missing)})",
            "dependent value given without a full state",
        )
    return given_dep


def _complete(system: System, variant: str, params, given, full: dict) -> None:
    """Solve the dependent values of ``full`` (in place) from the constraints of ``variant``."""
    b = built(system)
    module, info = b.kernel(variant)
    xc = np.array([full.get(s, 0.0) for s in info.state_names], float)
    try:
        xc = complete_state(module, info, xc, b.param_vector(variant, params), b.partitions.get(variant))
    except ConvergenceError as e:
        dep = [k for k in b.state_names if k not in b.independent]
        raise InputError(
            "initial",
            given,
            f"independent values ({', '.join(b.independent)}) for which the constraints can be "
            f"solved for the dependent ones ({', '.join(dep)}) with the parameters given — change them, "
            f"or give a full consistent state; the system's default_initial holds the starting "
            f"guesses of the dependent values (they pick the branch)",
            str(e),
        ) from None
    for s, v in zip(info.state_names, xc, strict=True):
        full[s] = float(v)


def _project(system: System, variant: str, params, given, full: dict, correction: dict | None) -> None:
    """Move the full state ``full`` (in place) onto the constraint manifold of ``variant``."""
    b = built(system)
    module, info = b.kernel(variant)
    xc = np.array([full[s] for s in info.state_names], float)
    try:
        rank = max_rank(system, variant, default_state(system))
        y = project_onto_manifold(module, info, xc, b.param_vector(variant, params), rank)
    except ConvergenceError as e:
        raise InputError("initial", given, "a state that can be projected onto the constraints", str(e)) from None
    for s, a, c in zip(info.state_names, xc, y, strict=True):
        full[s] = float(c)
        if correction is not None and a != c:
            correction[s] = float(c - a)


def _check_consistent(system: System, variant: str, params, full: dict, checks: list[str]) -> None:
    """The state must satisfy the constraints of every variant in ``checks`` (the chosen one,
    and the completion variant for completed or full states: it may exclude branches the
    chosen variant admits)."""
    b = built(system)
    failed = {}
    for var in dict.fromkeys(checks):
        module, info = b.kernel(var)
        if any(s not in full for s in info.state_names):
            continue
        xv = np.array([full[s] for s in info.state_names], float)
        E, V = np.empty(1), np.empty((1, module.NV))  # the run's own diagnostics: no other compile
        module.diagnostics_rows(np.zeros(1), xv[None, :], b.param_vector(var, params), E, V)
        viol = V[0, : info.m]
        bad = {name: float(val) for name, val in zip(info.constraint_names, viol, strict=True) if abs(val) > CHECK_TOL}
        if bad:
            failed[var] = ", ".join(f"{k} = {v:.3g}" for k, v in bad.items())
    if not failed:
        return
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
        {k: full[k] for k in b.state_names},
        f"a state satisfying the constraints of the {' and '.join(dict.fromkeys(checks))} "
        f"{system.option} within {CHECK_TOL:g}",
        reason,
    )
