"""Settings in, a checked :class:`Plan` out.

:func:`resolve` checks a :class:`~nmkane_core.schema.RunSettings` against the system (every
error names the field, the value and what is allowed), fills in the system's defaults, and
warns about gains whose constraint-error dynamics are not stable.  Ranges of single fields
are the schema's own (:mod:`nmkane_core.run.settings`); what is checked here is what needs
the system or several fields at once: the variant, the step budget, the gains' shapes, the
projection, the initial state.  :meth:`Plan.job` is what the loop drivers integrate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields

import numpy as np

from ..declare.system import System
from ..errors import InputError
from ..integrate.job import Alternative, Job
from ..integrate.methods import ScipyMethod, Tableau, get_integrator
from ..integrate.projection import ProjectionOptions, projection_options
from ..kernel.built import built
from ..kernel.info import ModelInfo
from ..schema import LIMITS, RunSettings
from .bounds import run_bounds
from .initial import default_state, initial_state
from .partition import max_rank, partition
from .registry import get_system, system_names
from .settings import raise_all, shown, validate_settings
from .solvelog import robust_in_use

__all__ = [
    "Plan",
    "check_budget",
    "default_projection",
    "min_every",
    "output_rows",
    "resolve",
    "round_up",
    "validate_settings",
]


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
    forces: bool = True  # report constraint forces and multipliers
    solve: int = 2  # the constraint solve (kernels with the rank-robust one): 0 paper, 1 robust, 2 auto
    max_rank: int = -1  # independent constraint equations (n − p, or the rank at the default state)
    order: tuple[int, ...] = ()  # the partition to start with, as the kernel's column order
    drift_limit: float = math.inf  # |E − E0| past this ends the run "drifted" (run.bounds)
    violation_limit: float = math.inf  # a reported violation past this too
    output_times: tuple[float, ...] | None = None  # report the state at these times only (run.timeline)
    stop_events: frozenset[str] = frozenset()  # declared events that end the run (run.events)
    near_projection: ProjectionOptions | None = None  # without a projection: the steps near a singular position

    @property
    def info(self) -> ModelInfo:
        return built(self.system).info(self.variant)

    def job(self) -> Job:
        """What the loop drivers integrate: the numbers and kernels of this plan (with the
        equivalent variants it may switch to, when switching is on)."""
        b = built(self.system)
        alternatives = tuple(
            Alternative(v, b.module(v), b.param_vector(v, self.params))
            for v in (self.system.equivalents.get(self.variant, ()) if self.switching else ())
        )
        # the numbers a job shares with the plan are copied by name: a new setting is a field of
        # each, not a line here
        shared = {f.name: getattr(self, f.name) for f in fields(Job) if f.name in _PLAN_FIELDS}
        return Job(
            method=self.integrator,
            module=b.module(self.variant),
            proj=self.projection.as_array(self.info),
            near_proj=self.near_projection.as_array(self.info) if self.near_projection is not None else None,
            alternatives=alternatives,
            **shared,
        )


_PLAN_FIELDS = frozenset(f.name for f in fields(Plan))


def resolve(settings: RunSettings | Mapping, max_rows: int | None = None) -> Plan:
    """Check settings against the system and fill in defaults.  ``max_rows``: the output row cap
    an unset ``every`` keeps a run within (default: the library's, ``LIMITS["max_rows"]``; the
    service gives its own)."""
    s = settings if isinstance(settings, RunSettings) else validate_settings(settings)
    system = get_system(s.system if s.system is not None else system_names()[0])
    variant = _variant(system, s)
    method = get_integrator(s.integrator or system.default_integrator)
    dt = s.dt if s.dt is not None else system.default_dt
    t_final = s.t_final if s.t_final is not None else system.default_t_final
    warnings: list[str] = []
    every = _every(s, method, dt, t_final, max_rows or LIMITS["max_rows"], warnings)
    check_budget(method, dt, t_final, every, LIMITS["max_steps"], LIMITS["max_rows"])
    params = system.resolve_params(s.params)
    b = built(system)
    info = b.info(variant)
    where = system.name if len(system.variants) == 1 else f"the {variant} {system.option} of {system.name}"
    proj = _projection(s, system, variant, method, info, where, warnings)
    solve, rank, order = _solve(s, system, variant, where)
    G, G1, G2 = _gains(s, system, info, where, warnings)
    correction: dict[str, float] = {}
    x0, full = initial_state(system, variant, params, dict(s.initial), project=s.project_initial, correction=correction)
    p = b.param_vector(variant, params)
    _check_finite_start(system, variant, p, x0, full)
    drift_limit, violation_limit = run_bounds(s, b.module(variant), info, x0, p)
    output_times = _output_times(s.output_times, t_final)
    near = _near_projection(s, b.module(variant), method, proj, solve)
    stop_events = _stop_events(s.stop_at, system)
    if correction:
        warnings.append(
            "the initial state was projected onto the constraint manifold: "
            + ", ".join(f"{k} {v:+.3g}" for k, v in correction.items())
        )
    return Plan(
        system=system,
        variant=variant,
        integrator=method,
        params=params,
        p=p,
        G=G,
        G1=G1,
        G2=G2,
        dt=dt,
        t_final=t_final,
        every=every,
        rtol=s.rtol,
        atol=s.atol,
        rcond_min=s.rcond_min,
        rcond_switch=s.rcond_switch,
        switching=s.switching,
        projection=proj,
        x0=x0,
        initial=full,
        settings={**_resolved(s, system, variant, method, dt, t_final, params, full, proj), "every": every},
        warnings=warnings,
        initial_correction=correction,
        forces=s.constraint_forces,
        solve=solve,
        max_rank=rank,
        order=order,
        drift_limit=drift_limit,
        violation_limit=violation_limit,
        output_times=output_times,
        stop_events=stop_events,
        near_projection=near,
    )


def _near_projection(s: RunSettings, module, method, proj: ProjectionOptions, solve: int) -> ProjectionOptions | None:
    """The projection of the steps that come near a singular position, in a run without one
    (``singular_projection``): the mass metric's (yoon), for the tableau methods of a model
    whose kernel runs the rank-robust machinery (csrc/loops.c ``step_projection``)."""
    if not s.singular_projection or proj.name != "none" or method.kind == "scipy" or not robust_in_use(module, solve):
        return None
    return projection_options("yoon")


def _output_times(times: list[float] | None, t_final: float) -> tuple[float, ...] | None:
    """The asked output times, checked: finite, increasing, within [0, t_final]."""
    if times is None:
        return None
    for i, t in enumerate(times):
        if not (math.isfinite(t) and 0.0 <= t <= t_final):
            raise InputError(f"output_times[{i}]", t, f"0 ≤ t ≤ t_final = {t_final:g} s", "outside the run")
        if i and not t > times[i - 1]:
            raise InputError(
                f"output_times[{i}]", t, f"greater than output_times[{i - 1}] = {times[i - 1]:g}", "not increasing"
            )
    return tuple(float(t) for t in times)


def _stop_events(stop_at: list[str] | None, system: System) -> frozenset[str]:
    """The events that end the run: the request's, or the system's stop_events (all)."""
    from ..kernel.events import compile_events

    compiled = compile_events(system) if system.events is not None else None
    names = tuple(compiled.names) if compiled is not None else ()
    chosen = stop_at if stop_at is not None else (system.stop_events if system.stop_events is not None else names)
    for name in chosen:
        if name not in names:
            allowed = " | ".join(names) if names else f"none: {system.name} declares no events"
            raise InputError("stop_at", name, allowed, "not an event of the system")
    return frozenset(chosen)


def _variant(system: System, s: RunSettings) -> str:
    """The variant asked for under the system's own option (``model`` or ``formulation``)."""
    other = "formulation" if system.option == "model" else "model"
    if getattr(s, other) is not None:
        raise InputError(
            other,
            getattr(s, other),
            f"{system.option}: {' | '.join(system.variants)} ({system.name} has no {other})",
            f"{system.name} has no {other}",
        )
    return system.check_variant(getattr(s, system.option), system.option)


def _every(s: RunSettings, method, dt: float, t_final: float, max_rows: int, warnings: list[str]) -> int:
    """``every`` as given, or (unset) 1, or, for a fixed-step run with more steps than ``max_rows``
    output rows, the smallest ``every`` that keeps it within them, said in a warning."""
    if s.every is not None:
        return s.every
    if method.kind != "fixed":
        return 1
    nsteps = math.ceil(t_final / dt - 1e-9)
    every = min_every(nsteps, max_rows)
    if every > 1:
        warnings.append(
            f"every = {every}: one output row every {every} steps of the run's {nsteps:,}, within {max_rows:,} "
            "rows (set every to choose; the maxima use every step)"
        )
    return every


def check_budget(method, dt: float, t_final: float, every: int, max_steps: int, max_rows: int, where: str = "") -> None:
    """A fixed-step run's steps (t_final/dt) and output rows within ``max_steps`` and
    ``max_rows``; every violated limit is named at once, with the ``dt`` or ``every`` that would
    do (``where``: whose limits, e.g. " on this service").  Adaptive and scipy runs are bounded
    while they run."""
    if method.kind != "fixed":
        return
    nsteps = math.ceil(t_final / dt - 1e-9)
    errors = []
    if nsteps > max_steps:
        errors.append(
            InputError(
                "dt",
                dt,
                f"t_final/dt ≤ {max_steps:,} steps{where} (dt ≥ {round_up(t_final / max_steps):.3g} s for "
                f"t_final = {t_final:g} s)",
                f"{nsteps:,} steps",
            )
        )
    rows = output_rows(nsteps, every)
    if rows > max_rows:
        errors.append(
            InputError(
                "every",
                every,
                f"an integer ≥ {min_every(nsteps, max_rows)} (at most {max_rows:,} output rows{where})",
                f"{rows:,} rows",
            )
        )
    raise_all(errors)


def _gains(s: RunSettings, system: System, info: ModelInfo, where: str, warnings: list[str]):
    """Γ, Γ1, Γ2 as matrices for the model's constraints (scalars as Γ·I; defaults: the system's)."""
    requested = [
        ("gamma", s.gamma, system.default_gamma, info.nonholonomic, "nonholonomic"),
        ("gamma1", s.gamma1, system.default_gamma1, info.holonomic, "holonomic"),
        ("gamma2", s.gamma2, system.default_gamma2, info.holonomic, "holonomic"),
    ]
    errors, gains = [], []
    for name, value, default, constraints, kind in requested:
        try:
            gains.append(_gain(name, default if value is None else value, constraints, warnings, kind, where))
        except InputError as e:
            errors.append(e)
    raise_all(errors)
    G, G1, G2 = gains
    _warn_unstable(G, G1, G2, warnings)
    return G, G1, G2


def _gain(name: str, value, constraints: tuple[str, ...], warnings: list[str], kind: str, where: str) -> np.ndarray:
    """The gain matrix ``name`` for the ``constraints`` (their names) of one kind (``kind``:
    "nonholonomic" or "holonomic") of the model described by ``where``."""
    size = len(constraints)
    if size:
        what = f"{where} has {size} {kind} constraint{'s' if size > 1 else ''}: " + ", ".join(constraints)
    else:
        what = f"{where} has no {kind} constraints"
    limit = LIMITS["max_gain"]
    if isinstance(value, (int, float)):
        if not (math.isfinite(value) and abs(value) <= limit):
            raise InputError(name, value, f"a finite number in [{-limit:g}, {limit:g}]", "out of range")
        G = float(value) * np.eye(size)
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
        if not np.all(np.isfinite(G)) or np.abs(G).max(initial=0) > limit:
            raise InputError(name, value, f"finite entries with |Γ_ij| ≤ {limit:g}", "out of range")
    if size == 0 and value not in (None, 0, 0.0):
        warnings.append(f"{name} = {value!r} ignored: {what}")
    return G


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


SOLVES = {"paper": 0, "robust": 1, "auto": 2}


def _solve(s: RunSettings, system: System, variant: str, where: str) -> tuple[int, int, tuple[int, ...]]:
    """(solve code, the rank the robust solve may keep, the partition to start with as the
    kernel's column order) — the request's solve, or the system's default, checked against
    the variant's constraints."""
    module = built(system).module(variant)
    name = s.solve or system.default_solve
    if not module.ROBUST:  # no constraints: nothing to solve for
        return SOLVES[name], -1, ()
    rank = max_rank(system, variant, default_state(system))
    if name == "paper" and rank < module.M:
        raise InputError(
            "solve",
            name,
            f"auto | robust for {where}: its {module.M} constraint equations have rank {rank} (redundant ones), "
            "so no partition has a square, invertible J2",
            "no partition for the paper's solve",
        )
    return SOLVES[name], rank, partition(system, variant).order


def default_projection(system: System, variant: str | None = None) -> str:
    """The projection a run of ``variant`` gets when it names none: the system's
    ``default_projection``, with ``auto`` resolved — ``yoon`` where the variant's constraint
    equations are redundant (rank below their number: drift makes them inconsistent, and the
    mass-metric projection keeps the state where they agree), else ``none``."""
    name = system.default_projection
    if name != "auto":
        return name
    variant = system.check_variant(variant)
    m = built(system).info(variant).m
    return "yoon" if m and max_rank(system, variant, default_state(system)) < m else "none"


def _projection(
    s: RunSettings, system: System, variant: str, method, info: ModelInfo, where: str, warnings: list[str]
) -> ProjectionOptions:
    name: str = "none" if s.projection is None else s.projection
    if s.projection is None:  # the system's default — one a scipy solver cannot use is left out
        name = default_projection(system, variant)
        if name != "none" and method.kind == "scipy":
            warnings.append(f"{where} projects after each step by default ({name}); scipy integrators cannot: none")
            name = "none"
    proj = projection_options(
        name, s.projection_weight, s.projection_iterations, s.projection_jacobian, s.projection_energy
    )
    if proj.name != "none" and method.kind == "scipy":
        raise InputError(
            "projection",
            s.projection,
            "none with scipy integrators; blajer | yoon with rk4, kutta-merson, kutta-merson-adaptive",
            "post-step projection needs a tableau integrator",
        )
    if proj.name != "none" and info.m == 0:
        warnings.append(f"projection {proj.name} has nothing to do: {where} has no constraints")
    return proj


def _resolved(s: RunSettings, system: System, variant, method, dt, t_final, params, full, proj) -> dict:
    """The fully resolved request, as runs report it (``settings`` of the result document)."""
    other = "formulation" if system.option == "model" else "model"
    resolved = s.model_dump()
    resolved.update(
        {
            "system": system.name,
            system.option: variant,
            other: None,
            "integrator": method.name,
            "dt": dt,
            "t_final": t_final,
            "params": params,
            "initial": full,
            "gamma": system.default_gamma if s.gamma is None else s.gamma,
            "gamma1": system.default_gamma1 if s.gamma1 is None else s.gamma1,
            "gamma2": system.default_gamma2 if s.gamma2 is None else s.gamma2,
            "projection": proj.name,
            "solve": s.solve or system.default_solve,
        }
    )
    if proj.name != "none":
        resolved.update(
            projection_weight=proj.weight,
            projection_iterations=proj.iterations,
            projection_jacobian=proj.jacobian,
            projection_energy=proj.energy,
        )
    return resolved


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
            shown(full),
            "initial values small enough that the energy, the constraint terms and the outputs are finite numbers",
            f"{' and '.join(bad)} {verb} at t = 0",
        )


def round_up(x: float) -> float:
    """``x`` rounded up to three significant digits (a hint that is then accepted)."""
    if x <= 0 or not math.isfinite(x):
        return x
    scale = 10.0 ** (math.floor(math.log10(x)) - 2)
    return math.ceil(x / scale * (1 - 1e-12)) * scale


def output_rows(nsteps: int, every: int) -> int:
    """Output rows of a fixed-step run: the initial state, every ``every``-th step and the last."""
    return -(-nsteps // every) + 1


def min_every(nsteps: int, max_rows: int) -> int:
    """The smallest ``every`` that keeps a run of ``nsteps`` steps to ``max_rows`` output rows."""
    return max(1, -(-nsteps // (max_rows - 1)))
