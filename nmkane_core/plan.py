"""Settings in, a checked :class:`Plan` out.

:func:`resolve` checks a :class:`~nmkane_core.schema.RunSettings` against the system (every
error names the field, the value and what is allowed), fills in the defaults, and warns
about gains whose constraint-error dynamics are not stable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from .errors import InputError
from .initial import initial_state
from .integrators import ScipyMethod, Tableau, get_integrator
from .projection import ProjectionOptions, projection_options
from .schema import LIMITS, RunSettings
from .registry import get_system
from .system import System

__all__ = ["Plan", "resolve", "validate_settings"]

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


def _gain(name: str, value, constraints: tuple[str, ...], warnings: list[str], kind: str, where: str) -> np.ndarray:
    """The gain matrix ``name`` for the ``constraints`` (their names) of one kind (``kind``:
    "nonholonomic" or "holonomic") of the model described by ``where``."""
    size = len(constraints)
    if size:
        what = (f"{where} has {size} {kind} constraint{'s' if size > 1 else ''}: "
                + ", ".join(constraints))
    else:
        what = f"{where} has no {kind} constraints"
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
    where = system.name if len(system.variants) == 1 else f"the {variant} {system.option} of {system.name}"
    G = _gain("gamma", s.gamma if s.gamma is not None else system.default_gamma, md.nonholonomic, warnings,
              "nonholonomic", where)
    G1 = _gain("gamma1", s.gamma1 if s.gamma1 is not None else system.default_gamma1, md.holonomic, warnings,
               "holonomic", where)
    G2 = _gain("gamma2", s.gamma2 if s.gamma2 is not None else system.default_gamma2, md.holonomic, warnings,
               "holonomic", where)
    _warn_unstable(G, G1, G2, warnings)
    proj = projection_options(s.projection, s.projection_weight, s.projection_iterations,
                              s.projection_jacobian, s.projection_energy)
    if proj.name != "none" and isinstance(integ, ScipyMethod):
        raise InputError("projection", s.projection, "none with scipy integrators; blajer | yoon with "
                         "rk4, kutta-merson, kutta-merson-adaptive", "post-step projection needs a tableau integrator")
    if proj.name != "none" and md.m == 0:
        warnings.append(f"projection {proj.name} has nothing to do: {where} has no constraints")
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
