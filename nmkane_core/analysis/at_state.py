"""Analysis of any system at a state: accelerations, and the linearized equations of motion.

[`accelerations`][nmkane_core.accelerations] evaluates the nonminimal equations T u̇ = V (44) at a full consistent
state — without the stabilization terms, which vanish on the constraint manifold anyway —
and [`linearize`][nmkane_core.linearize] the state matrix of the independent coordinates and speeds about a
state, with its eigenvalues: the motion is perturbed in the independent values only, the
dependent ones being completed from the constraints (holonomic ψ(q) = 0 by Newton's method,
then the velocity constraints for u_D), so the linearization lives on the constraint
manifold.  Derivatives are central differences with Richardson extrapolation (error
O(h⁴)), which with the compiled kernel gives about ten correct digits.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..declare.system import System
from ..errors import InconsistentStateError, InputError
from ..kernel.built import built
from ..run.forces import point_forces_at
from ..run.initial import CHECK_TOL, complete_state
from ..run.registry import get_system

__all__ = ["Accelerations", "accelerations", "linearize", "Linearization"]


def _setup(system: System | str, state: Mapping[str, float], params, variant):
    system = get_system(system) if isinstance(system, str) else system
    variant = system.check_variant(variant)
    values = system.resolve_params(params or {})
    module, info = built(system).kernel(variant)
    p = built(system).param_vector(variant, values)
    names = info.state_names
    unknown = sorted(set(state) - set(names))
    if unknown:
        raise InputError(
            f"state.{unknown[0]}",
            state[unknown[0]],
            f"state names of {system.name}: {', '.join(names)}",
            "unknown state name",
        )
    missing = [k for k in names if k not in state]
    if missing:
        raise InputError(
            "state",
            dict(state),
            f"every coordinate and speed of {system.name} ({', '.join(names)})",
            f"missing {', '.join(missing)}",
        )
    x = np.array([float(state[k]) for k in names])
    if not np.all(np.isfinite(x)):
        raise InputError("state", dict(state), "finite numbers", "not finite")
    return system, variant, module, info, p, x


def _zero_gains(info):
    m_nh, m_h = len(info.nonholonomic), len(info.holonomic)
    return np.zeros((m_nh, m_nh)), np.zeros((m_h, m_h)), np.zeros((m_h, m_h))


def _check_consistent(system, module, info, x, p, tol):
    viol = module.state_terms(0.0, x, p)[4][: info.m]
    bad = {k: float(v) for k, v in zip(info.constraint_names, viol, strict=True) if abs(v) > tol}
    if bad:
        raise InconsistentStateError(
            "state",
            None,
            f"a state satisfying the constraints of {system.name} within {tol:g}",
            ", ".join(f"{k} = {v:.3g}" for k, v in bad.items()),
        )


class Accelerations(dict):
    """``{speed name: du/dt}`` (a plain dict to every caller) with the constraint forces at that
    state as attributes.

    Attributes
    ----------
    constraint_forces : dict of str to float
        F_c = Q u̇ − P by speed name (the generalized constraint force).
    multipliers : dict of str to float
        λ by constraint name, F_c = Jᵀλ.
    point_forces : dict of str to float
        The physical forces the system declares at points, by ``NAME.LABEL``
        (:mod:`nmkane_core.declare.forces`); empty when it declares none.
    """

    constraint_forces: dict[str, float]
    multipliers: dict[str, float]
    point_forces: dict[str, float]

    def __init__(self, du, constraint_forces=None, multipliers=None, point_forces=None):
        super().__init__(du)
        self.constraint_forces = dict(constraint_forces or {})
        self.multipliers = dict(multipliers or {})
        self.point_forces = dict(point_forces or {})


def accelerations(
    system: System | str,
    state: Mapping[str, float],
    params: Mapping[str, float] | None = None,
    variant: str | None = None,
    t: float = 0.0,
) -> Accelerations:
    """du/dt of every speed at a full consistent state (all q and u), no stabilization terms —
    and the constraint forces there.

    Evaluates the nonminimal equations T u̇ = V (44); the Baumgarte terms vanish on the
    constraint manifold anyway.

    Parameters
    ----------
    system : System or str
        A [`System`][nmkane_core.System] or a registered name.
    state : mapping of str to float
        Every coordinate and speed name to its value.
    params : mapping of str to float, optional
        Parameter values overriding the system's defaults.
    variant : str, optional
        Which model (default: the system's).
    t : float, optional
        The time, for models that depend on it.

    Returns
    -------
    Accelerations
        Speed name → du/dt (a dict), with the constraint forces there as attributes:
        ``constraint_forces`` (F_c = Q u̇ − P by speed), ``multipliers`` (λ by constraint) and
        ``point_forces`` (the system's declared forces at points, ``NAME.LABEL``).

    Raises
    ------
    InputError
        For unknown or missing names, or a state where J2 or T is singular.
    InconsistentStateError
        When the state violates the constraints.
    """
    sys_, variant, module, info, p, x = _setup(system, state, params, variant)
    _check_consistent(sys_, module, info, x, p, CHECK_TOL)
    gains = _zero_gains(info)
    xdot, _, _ = module.rhs(t, x, p, *gains)
    if not np.all(np.isfinite(xdot)):
        raise InputError("state", dict(state), "a state where J2 and T are invertible", "singular there")
    F, L = np.zeros((1, info.n)), np.zeros((1, info.m))
    module.forces_rows(np.array([float(t)]), x[None, :], p, *gains, F, L)
    fc = {name: float(v) for name, v in zip(info.u, F[0], strict=True)}
    lam = {name: float(v) for name, v in zip(info.constraint_names, L[0], strict=True)}
    full = {name: float(v) for name, v in zip(info.state_names, x, strict=True)}
    if info.outputs:
        O = np.empty((1, len(info.outputs)))
        module.outputs_rows(np.array([float(t)]), x[None, :], p, O)
        full.update({name: float(v) for name, v in zip(info.outputs, O[0], strict=True)})
    values = sys_.resolve_params(params or {})
    at_points = point_forces_at(sys_, variant, t, full, values, lam, fc, xdot)
    du = {name: float(v) for name, v in zip(info.u, xdot[info.n :], strict=True)}
    return Accelerations(du, fc, lam, at_points)


@dataclass(frozen=True)
class Linearization:
    """ż ≈ A (z − z0) for z = the kept independent coordinates and speeds (``names``).

    Attributes
    ----------
    names : tuple of str
        The kept independent coordinates and speeds, in the order of ``A``'s rows.
    A : numpy.ndarray
        The state matrix.
    eigenvalues : numpy.ndarray
        Its eigenvalues (complex).
    """

    names: tuple[str, ...]
    A: np.ndarray
    eigenvalues: np.ndarray

    def as_dict(self) -> dict:
        """JSON-ready: ``names``, ``A`` as nested lists, eigenvalues as ``[re, im]`` pairs."""
        return {
            "names": list(self.names),
            "A": self.A.tolist(),
            "eigenvalues": [[float(v.real), float(v.imag)] for v in self.eigenvalues],
        }


def linearize(
    system: System | str,
    state: Mapping[str, float],
    params: Mapping[str, float] | None = None,
    variant: str | None = None,
    keep: Sequence[str] | None = None,
    step: float = 1e-3,
) -> Linearization:
    """The state matrix of the independent coordinates and speeds about ``state``, and its eigenvalues.

    Only the independent values are perturbed; the dependent ones are completed from the
    constraints, so the linearization lives on the constraint manifold.

    Parameters
    ----------
    system : System or str
        A [`System`][nmkane_core.System] or a registered name.
    state : mapping of str to float
        A full consistent state (every coordinate and speed).
    params : mapping of str to float, optional
        Parameter values overriding the system's defaults.
    variant : str, optional
        Which model (default: the system's).
    keep : sequence of str, optional
        Which independent coordinates and speeds form the linearized state (default: all of
        them); leave out coordinates the motion does not depend on (a position in the
        plane, a heading, a wheel angle) — for a vehicle on wheels, keep roll, steer and their rates.
    step : float, optional
        The perturbation size of the central differences (scaled by each value's magnitude).

    Returns
    -------
    Linearization
        ``names``, the state matrix ``A`` and its ``eigenvalues``.

    Raises
    ------
    InputError
        For unknown names, or a kept name that is not independent.
    InconsistentStateError
        When the state violates the constraints.
    """
    sysm, variant, module, info, p, x0 = _setup(system, state, params, variant)
    _check_consistent(sysm, module, info, x0, p, CHECK_TOL)
    q_ind = [q for q in info.q if q not in info.q_dependent]
    u_ind = list(info.u_independent) if info.m else list(info.u)
    independent = q_ind + u_ind
    names = list(keep) if keep is not None else independent
    bad = [k for k in names if k not in independent]
    if bad:
        raise InputError(
            f"keep.{bad[0]}",
            bad[0],
            f"independent coordinates and speeds of {sysm.name}: {', '.join(independent)}",
            "not independent",
        )
    index = [info.state_names.index(k) for k in names]
    gains = _zero_gains(info)

    def f(z: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[index] = z
        x = complete_state(module, info, x, p)  # back onto the constraint manifold
        xdot, _, _ = module.rhs(0.0, x, p, *gains)
        return xdot[index]

    z0 = x0[index]
    A = np.empty((len(index), len(index)))
    for j in range(len(index)):
        h = step * max(1.0, abs(z0[j]))

        def d(hh: float, j: int = j) -> np.ndarray:
            e = np.zeros_like(z0)
            e[j] = hh
            return (f(z0 + e) - f(z0 - e)) / (2 * hh)

        A[:, j] = (4 * d(h / 2) - d(h)) / 3  # Richardson: O(h⁴)
    if not np.all(np.isfinite(A)):
        raise InputError("state", dict(state), "a state where J2 and T are invertible", "singular there")
    return Linearization(tuple(names), A, np.linalg.eigvals(A))
