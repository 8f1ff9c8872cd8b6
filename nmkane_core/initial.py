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

import numpy as np

from .errors import ConvergenceError, InconsistentStateError, InputError
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .system import System

__all__ = ["initial_state", "CHECK_TOL"]

#: absolute tolerance on each constraint residual of a given full state
CHECK_TOL = 1e-8


def _newton(residual, x, idx, label, tol=1e-13, maxit=60):
    """Solve residual(x)[0] = 0 for x[idx]; residual returns (r, dr/dx[idx])."""
    x = x.copy()
    r = np.zeros(0)
    for _ in range(maxit):
        r, jac = residual(x)
        if np.all(np.abs(r) <= tol * (1.0 + np.abs(x[idx]).max(initial=0.0))):
            return x
        try:
            step = np.linalg.solve(jac, r)
        except np.linalg.LinAlgError:
            raise ConvergenceError(f"{label}: the constraint Jacobian is singular at the guess") from None
        x[idx] -= step
        if not np.all(np.isfinite(x)):
            break
    raise ConvergenceError(f"{label}: Newton did not converge in {maxit} iterations "
                           f"(residual {np.abs(r).max(initial=0.0):.3g})")


def complete_state(module, info, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Solve the dependent coordinates and speeds of ``x`` (model order) from the constraints."""
    n = info.n
    if info.holonomic:
        qi = [info.q.index(s) for s in info.q_dependent]

        def holo(z):
            _, _, psi, psi_q, _ = module.state_terms(0.0, z, p)
            return psi, psi_q[:, qi]

        x = _newton(holo, x, qi, "holonomic constraints ψ(q) = 0")
    if info.m:
        ui = [n + info.u.index(s) for s in info.u if s not in info.u_independent]

        def vel(z):
            J, c, _, _, _ = module.state_terms(0.0, z, p)
            return c, J[:, [i - n for i in ui]]

        x = _newton(vel, x, ui, "velocity constraints [φ; ψ̇] = 0")
    return x


def project_onto_manifold(module, info, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The nearest consistent state (Euclidean metric): positions onto ψ = 0, then speeds onto
    [φ; ψ̇] = 0 at the corrected positions (the kernel's post-step projection, iterated)."""
    from .projection import ProjectionOptions

    proj = ProjectionOptions("onto-manifold", weight="identity", iterations=20, jacobian="updated",
                             energy=False).as_array(info)
    y, code = module.project_state(0.0, x, p, proj)
    if code != 0 or not np.all(np.isfinite(y)):
        raise ConvergenceError("the projection onto the constraint manifold met a singular matrix")
    return y


def initial_state(system: System, variant: str, params: dict[str, float],
                  given: dict[str, float], project: bool = False,
                  correction: dict | None = None, complete_always: bool = False
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
            raise InputError(f"initial.{k}", v, f"state names of {system.name}: {', '.join(names)}",
                             "unknown state name")
        if not np.isfinite(v):
            raise InputError(f"initial.{k}", v, "a finite number", "not finite")
    full = dict(system.default_initial)
    full.update(given)
    dependent = [k for k in names if k not in system.independent]
    given_dep = [k for k in dependent if k in given]
    if given_dep and len(given) < len(names):
        missing = [k for k in names if k not in given]
        raise InputError(f"initial.{given_dep[0]}", given[given_dep[0]],
                         f"either independent values only ({', '.join(system.independent)}), "
                         f"the rest being completed, or a full state (missing: {', '.join(missing)})",
                         "dependent value given without a full state")
    # the default state is consistent for the default parameters; anything else given
    # without dependent values is completed
    defaults = all(params[q.name] == q.default for q in system.parameters)
    complete = not given_dep and (bool(given) or not defaults or complete_always
                                  or any(k not in full for k in names))
    comp_variant = system.completion_variant or variant
    p = system.param_vector(comp_variant, params)
    if complete:
        module, info = system.kernel(comp_variant)
        xc = np.array([full.get(s, 0.0) for s in info.state_names], float)
        try:
            xc = complete_state(module, info, xc, p)
        except ConvergenceError as e:
            raise InputError("initial", given, "values for which the constraints can be solved", str(e)) from None
        for s, v in zip(info.state_names, xc):
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
        for s, a, b in zip(info.state_names, xc, y):
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
        viol = module.state_terms(0.0, xv, p)[4][:info.m]
        bad = {name: float(val) for name, val in zip(info.constraint_names, viol) if abs(val) > CHECK_TOL}
        if bad:
            failed[var] = ", ".join(f"{k} = {v:.3g}" for k, v in bad.items())
    if failed:
        if variant not in failed:
            other = next(iter(failed))
            reason = (f"the state satisfies the constraints of the {variant} {system.option} but not those "
                      f"of the {other} {system.option} ({failed[other]}): it lies on a spurious branch of "
                      f"the {variant} constraints that the mechanism excludes")
        else:
            reason = "constraint residuals " + "; ".join(f"{v} {system.option}: {d}" for v, d in failed.items())
        raise InconsistentStateError(
            "initial", {k: full[k] for k in names},
            f"a state satisfying the constraints of the {' and '.join(dict.fromkeys(checks))} "
            f"{system.option} within {CHECK_TOL:g}", reason)
    info = system.info(variant)
    x0 = np.array([full[s] for s in info.state_names], float)
    return x0, {k: float(full[k]) for k in names}
