"""Settings in, a checked :class:`Plan` out.

:func:`resolve` checks a :class:`~nmkane_core.schema.RunSettings` against the system (every
error names the field, the value and what is allowed), fills in the defaults, and warns
about gains whose constraint-error dynamics are not stable.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from ..declare.system import System
from ..errors import InputError
from ..integrate.methods import ScipyMethod, Tableau, get_integrator
from ..integrate.projection import ProjectionOptions, projection_options
from ..kernel.built import built
from ..schema import LIMITS, RunSettings
from .initial import initial_state
from .registry import get_system

__all__ = ["Plan", "min_every", "output_rows", "raise_all", "resolve", "round_up", "validate_settings"]


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
    projection: ProjectionOptions
    x0: np.ndarray
    initial: dict[str, float]
    settings: dict
    warnings: list[str] = field(default_factory=list)
    initial_correction: dict[str, float] = field(default_factory=dict)

    @property
    def info(self):
        return built(self.system).info(self.variant)


def validate_settings(settings: Mapping) -> RunSettings:
    """The schema's checks (types, finite numbers, ranges) with errors as :class:`InputError`.

    ``settings``: a mapping of run settings (a dict; numpy scalars and arrays and tuples are
    taken as the numbers and lists they hold).  Validation is strict, as on the REST service:
    no booleans or numeric strings for numbers, no 2.0 for an integer.  Every violated field
    is named in one message (the error's ``errors`` lists them one by one).
    """
    from pydantic import ValidationError

    if not isinstance(settings, Mapping):
        raise InputError(
            "settings",
            _shown(settings),
            "a mapping (dict) of run settings, e.g. {'system': 'appell-hamel', 'dt': 0.01}",
            f"a {type(settings).__name__}",
        )
    try:
        return RunSettings.model_validate(_plain_data(dict(settings)), strict=True)
    except ValidationError as e:
        errors = []
        for err in e.errors():
            field = ".".join(str(p) for p in err["loc"]) or "settings"
            errors.append(InputError(field, _shown(err.get("input")), err["msg"].replace("Input should be", "a value")))
        raise_all(errors)
        raise AssertionError("unreachable") from None  # pragma: no cover


def raise_all(errors: list[InputError]) -> None:
    """Raise the one error, or one :class:`InputError` naming every field (its ``errors``
    attribute keeps them one by one, for a REST answer with one item each)."""
    if not errors:
        return
    if len(errors) == 1:
        raise errors[0]
    first = errors[0]
    combined = InputError(first.field, first.value, first.allowed, first.reason)
    combined.args = ("; ".join(str(e) for e in errors) + f" ({len(errors)} problems)",)
    combined.errors = errors  # type: ignore[attr-defined]
    raise combined


def _plain_data(value, depth: int = 0):
    """numpy scalars and arrays, and tuples, as the Python numbers and lists they hold."""
    if depth > 8:
        return value
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return [_plain_data(v, depth + 1) for v in value]
    if isinstance(value, list):
        return [_plain_data(v, depth + 1) for v in value]
    if isinstance(value, dict):
        return {k: _plain_data(v, depth + 1) for k, v in value.items()}
    return value


def _shown(value, depth: int = 0):
    """``value``, or a short text standing for it when it is too large or deep to print."""
    if isinstance(value, bool) or value is None or isinstance(value, float):
        return value
    if isinstance(value, int):
        if abs(value) < 10**30:
            return value
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1:,} digits"
    if isinstance(value, str):
        return value if len(value) <= 200 else value[:200] + f"… ({len(value)} characters)"
    if isinstance(value, (list, tuple, dict)):
        if depth >= 4:
            return f"a {type(value).__name__} nested too deeply to show"
        items = list(value.items()) if isinstance(value, dict) else list(value)
        if len(items) > 20:
            return f"a {type(value).__name__} of {len(items)} items"
        if isinstance(value, dict):
            return {k: _shown(v, depth + 1) for k, v in items}
        return type(value)(_shown(v, depth + 1) for v in items)
    text = repr(value)
    return value if len(text) <= 200 else text[:200] + "…"


def round_up(x: float) -> float:
    """``x`` rounded up to three significant digits (a hint that is then accepted)."""
    if x <= 0 or not math.isfinite(x):
        return x
    scale = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x / scale * (1 - 1e-12)) * scale


def _check_float(name, value, lo, hi, lo_open=True, unit=""):
    v = float(value)
    ok = (v > lo if lo_open else v >= lo) and v <= hi and math.isfinite(v)
    if not ok:
        bracket = "(" if lo_open else "["
        raise InputError(
            name,
            value,
            f"a finite number in {bracket}{lo:g}, {hi:g}]{' ' + unit if unit else ''}",
            "out of range" if math.isfinite(v) else "not finite",
        )
    return v


def _gain(name: str, value, constraints: tuple[str, ...], warnings: list[str], kind: str, where: str) -> np.ndarray:
    """The gain matrix ``name`` for the ``constraints`` (their names) of one kind (``kind``:
    "nonholonomic" or "holonomic") of the model described by ``where``."""
    size = len(constraints)
    if size:
        what = f"{where} has {size} {kind} constraint{'s' if size > 1 else ''}: " + ", ".join(constraints)
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
            raise InputError(
                name,
                value,
                f"a number or a {size}×{size} matrix"
                + (f" ({what})" if size == 0 else " (one row and column per constraint)"),
                f"shape {G.shape}",
            )
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
        raise InputError(
            other,
            getattr(s, other),
            f"{system.option}: {' | '.join(system.variants)} ({system.name} has no {other})",
            f"{system.name} has no {other}",
        )
    variant = system.check_variant(getattr(s, system.option), system.option)
    integ = get_integrator(s.integrator or system.default_integrator)
    errors: list[InputError] = []

    def check(fn, *args, **kw):
        try:
            return fn(*args, **kw)
        except InputError as e:
            errors.append(e)
            return None

    dt = check(_check_float, "dt", s.dt if s.dt is not None else system.default_dt, 0.0, LIMITS["max_dt"], unit="s")
    if dt is not None and dt < LIMITS["min_dt"]:
        errors.append(InputError("dt", dt, f"a number in [{LIMITS['min_dt']:g}, {LIMITS['max_dt']:g}] s", "too small"))
        dt = None
    t_final = check(
        _check_float,
        "t_final",
        s.t_final if s.t_final is not None else system.default_t_final,
        0.0,
        LIMITS["max_t_final"],
        unit="s",
    )
    every: int | None = s.every
    if s.every < 1 or s.every > LIMITS["max_steps"]:
        errors.append(InputError("every", every, f"an integer in [1, {LIMITS['max_steps']}]"))
        every = None
    if dt is not None and t_final is not None and isinstance(integ, Tableau) and not integ.adaptive:
        nsteps = math.ceil(t_final / dt - 1e-9)
        if nsteps > LIMITS["max_steps"]:
            errors.append(
                InputError(
                    "dt",
                    dt,
                    f"t_final/dt ≤ {LIMITS['max_steps']:,} steps "
                    f"(dt ≥ {round_up(t_final / LIMITS['max_steps']):.3g} s for "
                    f"t_final = {t_final:g} s)",
                    f"{nsteps:,} steps",
                )
            )
        elif every is not None:
            rows = output_rows(nsteps, every)
            if rows > LIMITS["max_rows"]:
                errors.append(
                    InputError(
                        "every",
                        every,
                        f"an integer ≥ {min_every(int(nsteps), LIMITS['max_rows'])} "
                        f"(at most {LIMITS['max_rows']:,} output rows)",
                        f"{rows:,} rows",
                    )
                )
    rtol = check(_check_float, "rtol", s.rtol, 0.0, 0.1)
    if rtol is not None and rtol < 1e-14:
        errors.append(InputError("rtol", s.rtol, "a number in [1e-14, 0.1]", "too small"))
    atol = check(_check_float, "atol", s.atol, 0.0, 1.0)
    rcond_min = check(_check_float, "rcond_min", s.rcond_min, 0.0, 0.1, lo_open=False)
    rcond_switch = check(_check_float, "rcond_switch", s.rcond_switch, 0.0, 0.5, lo_open=False)
    raise_all(errors)
    assert dt is not None and t_final is not None and rtol is not None and atol is not None
    assert rcond_min is not None and rcond_switch is not None
    params = system.resolve_params(s.params)
    p = built(system).param_vector(variant, params)
    md = built(system).info(variant)
    warnings: list[str] = []
    where = system.name if len(system.variants) == 1 else f"the {variant} {system.option} of {system.name}"
    G = _gain(
        "gamma",
        s.gamma if s.gamma is not None else system.default_gamma,
        md.nonholonomic,
        warnings,
        "nonholonomic",
        where,
    )
    G1 = _gain(
        "gamma1",
        s.gamma1 if s.gamma1 is not None else system.default_gamma1,
        md.holonomic,
        warnings,
        "holonomic",
        where,
    )
    G2 = _gain(
        "gamma2",
        s.gamma2 if s.gamma2 is not None else system.default_gamma2,
        md.holonomic,
        warnings,
        "holonomic",
        where,
    )
    _warn_unstable(G, G1, G2, warnings)
    proj = projection_options(
        s.projection, s.projection_weight, s.projection_iterations, s.projection_jacobian, s.projection_energy
    )
    if proj.name != "none" and isinstance(integ, ScipyMethod):
        raise InputError(
            "projection",
            s.projection,
            "none with scipy integrators; blajer | yoon with rk4, kutta-merson, kutta-merson-adaptive",
            "post-step projection needs a tableau integrator",
        )
    if proj.name != "none" and md.m == 0:
        warnings.append(f"projection {proj.name} has nothing to do: {where} has no constraints")
    correction: dict[str, float] = {}
    x0, full = initial_state(system, variant, params, dict(s.initial), project=s.project_initial, correction=correction)
    _check_finite_start(system, variant, p, x0, full)
    if correction:
        warnings.append(
            "the initial state was projected onto the constraint manifold: "
            + ", ".join(f"{k} {v:+.3g}" for k, v in correction.items())
        )
    resolved = s.model_dump()
    resolved.update(
        {
            system.option: variant,
            other: None,
            "integrator": integ.name,
            "dt": dt,
            "t_final": t_final,
            "params": params,
            "initial": full,
            "gamma": _plain(s.gamma, system.default_gamma),
            "gamma1": _plain(s.gamma1, system.default_gamma1),
            "gamma2": _plain(s.gamma2, system.default_gamma2),
        }
    )
    if proj.name != "none":
        resolved.update(
            projection_weight=proj.weight,
            projection_iterations=proj.iterations,
            projection_jacobian=proj.jacobian,
            projection_energy=proj.energy,
        )
    plan = Plan(
        system,
        variant,
        integ,
        params,
        p,
        G,
        G1,
        G2,
        dt,
        t_final,
        s.every,
        rtol,
        atol,
        rcond_min,
        rcond_switch,
        s.switching,
        proj,
        x0,
        full,
        resolved,
        warnings,
    )
    plan.initial_correction = correction
    return plan


def _check_finite_start(system: System, variant: str, p: np.ndarray, x0: np.ndarray, full: dict) -> None:
    """The energy, constraint violations and outputs at the initial state must be finite (a
    finite but huge state can overflow them: a run would have nothing finite to show)."""
    mod = built(system).module(variant)
    E, V, O = np.empty(1), np.empty((1, mod.NV)), np.empty((1, mod.NO))
    mod.diagnostics_rows(np.zeros(1), x0[None, :], p, E, V)
    if mod.NO:
        mod.outputs_rows(np.zeros(1), x0[None, :], p, O)
    bad = [
        what
        for what, ok in (
            ("the energy", not built(system).info(variant).has_energy or np.isfinite(E).all()),
            ("a constraint violation", np.isfinite(V).all()),
            ("an output", np.isfinite(O).all()),
        )
        if not ok
    ]
    if bad:
        verb = "overflows" if len(bad) == 1 else "overflow"
        raise InputError(
            "initial",
            _shown(full),
            "initial values small enough that the energy, the constraint terms and the outputs are finite numbers",
            f"{' and '.join(bad)} {verb} at t = 0",
        )


def output_rows(nsteps: int, every: int) -> int:
    """Output rows of a fixed-step run: the initial state, every ``every``-th step and the last."""
    return -(-nsteps // every) + 1


def min_every(nsteps: int, max_rows: int) -> int:
    """The smallest ``every`` that keeps a run of ``nsteps`` steps to ``max_rows`` output rows."""
    return max(1, -(-nsteps // (max_rows - 1)))


def _plain(v, default):
    return default if v is None else v


def _warn_unstable(G, G1, G2, warnings):
    if G.size and np.any(G) and np.any(np.linalg.eigvals(G).real >= 0):
        warnings.append(
            "Γ has eigenvalues with non-negative real part: the nonholonomic constraint "
            "error dynamics φ̇ = Γφ are not stable (stabilizing gains are negative)"
        )
    if G1.size and (np.any(G1) or np.any(G2)):
        k = G1.shape[0]
        comp = np.block([[np.zeros((k, k)), np.eye(k)], [G2, G1]])
        if np.any(np.linalg.eigvals(comp).real >= 0):
            warnings.append(
                "Γ1, Γ2 give constraint error dynamics ψ̈ = Γ1ψ̇ + Γ2ψ with eigenvalues of "
                "non-negative real part: not stable (e.g. Γ1 = −20, Γ2 = −100 are)"
            )
