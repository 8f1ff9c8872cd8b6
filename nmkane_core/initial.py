"""Consistent initial states: complete from independent values, or check a full state.

Given values for the *independent* coordinates and speeds (the rest taken from the
system's defaults), the dependent ones are solved from the constraints by Newton's
method: first the holonomic ψ(q) = 0 for the dependent coordinates, then the velocity
constraints [φ; ψ̇] = 0 for u_D.  A system may name a ``completion_variant`` (the
Appell–Hamel mechanism uses its linear model, whose velocity constraints have one
solution) — the state is then checked against the chosen variant's own constraints.
A full state (every name given) is not changed, only checked.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from .errors import ConvergenceError, InconsistentStateError, InputError
from .system import System

__all__ = ["initial_state", "CHECK_TOL"]

#: absolute tolerance on each constraint residual of a given full state
CHECK_TOL = 1e-8


class _ConstraintFunctions:
    def __init__(self, derivation):
        md = derivation.model
        self.model = md
        x = list(md.q) + list(md.u)
        args = [md.t, x, list(md.params)]
        d = derivation
        self.q_dep = list(md.q_dependent) if md.q_dependent else self._pick_q_dep(d)
        self.q_dep_idx = [list(md.q).index(s) for s in self.q_dep]
        self.u_dep_idx = [list(md.u).index(s) for s in md.u_dependent]
        lam = lambda e: sp.lambdify(args, e, modules="numpy")  # noqa: E731
        self.psi = lam(d.psi)
        self.psi_q = lam(d.psi.jacobian(sp.Matrix(self.q_dep)) if d.m_h else sp.zeros(0, 0))
        self.phi = lam(d.phi)
        self.phi_u = lam(d.J2)
        self.viol = lam(sp.Matrix(list(md.nonholonomic.values()) + list(md.holonomic.values())))
        self.m_h, self.m = d.m_h, d.m

    @staticmethod
    def _pick_q_dep(d):
        if not d.m_h:
            return []
        jac = d.psi.jacobian(d.q)
        chosen = []
        for i in range(d.m_h):  # first coordinate with a nonzero symbolic entry per row
            for j, qj in enumerate(d.q):
                if jac[i, j] != 0 and qj not in chosen:
                    chosen.append(qj)
                    break
        return chosen


@lru_cache(maxsize=None)
def _functions(system_name: str, variant: str):
    from .system import get_system

    return _ConstraintFunctions(get_system(system_name).derivation(variant))


def _newton(f, jac, z0, idx, x, label, tol=1e-13, maxit=60):
    x = x.copy()
    for _ in range(maxit):
        r = np.atleast_1d(np.asarray(f(x), float)).ravel()
        if np.all(np.abs(r) <= tol * (1.0 + np.abs(x[idx]).max(initial=0.0))):
            return x
        Jm = np.atleast_2d(np.asarray(jac(x), float))
        try:
            step = np.linalg.solve(Jm, r)
        except np.linalg.LinAlgError:
            raise ConvergenceError(f"{label}: the constraint Jacobian is singular at the guess") from None
        x[idx] -= step
        if not np.all(np.isfinite(x)):
            break
    raise ConvergenceError(f"{label}: Newton did not converge in {maxit} iterations "
                           f"(residual {np.abs(r).max():.3g})")


def _complete(fn: _ConstraintFunctions, x: np.ndarray, p: np.ndarray) -> np.ndarray:
    n = fn.model.n
    if fn.m_h:
        x = _newton(lambda z: fn.psi(0.0, z, p), lambda z: fn.psi_q(0.0, z, p), None,
                    fn.q_dep_idx, x, "holonomic constraints ψ(q) = 0")
    if fn.m:
        uidx = [n + i for i in fn.u_dep_idx]
        x = _newton(lambda z: fn.phi(0.0, z, p), lambda z: fn.phi_u(0.0, z, p), None,
                    uidx, x, "velocity constraints [φ; ψ̇] = 0")
    return x


def initial_state(system: System, variant: str, params: dict[str, float],
                  given: dict[str, float]) -> tuple[np.ndarray, dict[str, float]]:
    """The variant model's initial state vector and the full state (by name).

    Raises :class:`InputError` for unknown names, :class:`InconsistentStateError` when a
    full state violates the constraints by more than :data:`CHECK_TOL`.
    """
    names = system.state_names
    for k, v in given.items():
        if k not in names:
            raise InputError(f"initial.{k}", v, f"state names of {system.name}: {', '.join(names)}",
                             "unknown state name")
        if not np.isfinite(v):
            raise InputError(f"initial.{k}", v, "a finite number", "not finite")
    p = np.array([params[k] for k in system.param_names])
    full = dict(system.default_initial)
    full.update(given)
    dependent = [k for k in names if k not in system.independent]
    given_dep = [k for k in dependent if k in given]
    complete = not given_dep
    if given_dep and len(given) < len(names):
        missing = [k for k in names if k not in given]
        raise InputError(f"initial.{given_dep[0]}", given[given_dep[0]],
                         f"either independent values only ({', '.join(system.independent)}), "
                         f"the rest being completed, or a full state (missing: {', '.join(missing)})",
                         "dependent value given without a full state")
    comp_variant = system.completion_variant or variant
    fn = _functions(system.name, comp_variant)
    md_c = fn.model
    xc = np.array([full[str(s)] for s in md_c.q + md_c.u], float)
    if complete:
        try:
            xc = _complete(fn, xc, p)
        except ConvergenceError as e:
            raise InputError("initial", given, "values for which the constraints can be solved", str(e)) from None
        for s, v in zip(md_c.q + md_c.u, xc):
            full[str(s)] = float(v)
    # check against the completion variant and against the chosen variant
    for var in dict.fromkeys([comp_variant, variant]):
        f = _functions(system.name, var)
        md = f.model
        if any(str(s) not in full for s in md.q + md.u):
            continue
        xv = np.array([full[str(s)] for s in md.q + md.u], float)
        r = np.atleast_1d(np.asarray(f.viol(0.0, xv, p), float)).ravel()
        bad = {name: float(val) for name, val in zip(md.constraint_names, r) if abs(val) > CHECK_TOL}
        if bad:
            detail = ", ".join(f"{k} = {v:.3g}" for k, v in bad.items())
            raise InconsistentStateError(
                "initial", {k: full[k] for k in names},
                f"a state satisfying the constraints of the {var} {system.option} within {CHECK_TOL:g}",
                f"constraint residuals {detail}")
    md = system.model(variant)
    x0 = np.array([full[str(s)] for s in md.q + md.u], float)
    return x0, {k: float(full[k]) for k in names}
