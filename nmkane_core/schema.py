"""The one schema: run settings in, run result document out (CLI JSON, REST, web).

:class:`RunSettings` is what a user asks for (CLI options, REST body); omitted fields take
the system's defaults.  :class:`RunResult` is the run result document (README.md, "One
schema").  Both are pydantic models; the REST service uses them directly as its
request and response models and the CLI writes ``RunResult`` as its JSON.
"""

from __future__ import annotations

import math
import typing
from typing import Annotated, Any, Literal

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, WithJsonSchema
from pydantic_core import PydanticCustomError

__all__ = [
    "RunSettings",
    "RunSummary",
    "RunResult",
    "Switch",
    "Event",
    "ErrorEstimate",
    "LIMITS",
    "REST_DEFAULT_LIMITS",
    "Gain",
    "PROJECTIONS",
    "allowed",
    "field_range",
]

#: Library-wide limits (the REST service may impose lower ones; see /api/systems).
LIMITS: dict[str, Any] = {
    "max_steps": 50_000_000,  # fixed steps (or adaptive attempts) per run
    "max_rows": 2_000_000,  # output rows per run
    "max_t_final": 1e6,  # s
    "min_dt": 1e-7,  # s
    "max_dt": 10.0,  # s
    "max_gain": 1e6,  # |Γ| entries
}

#: The REST service's default limits per run (backend/config.py; raised with NMKANE_MAX_STEPS and
#: NMKANE_MAX_ROWS).  Kept here, in the core, so that the core can quote them without importing backend.
REST_DEFAULT_LIMITS: dict[str, int] = {
    "max_steps": 2_000_000,  # fixed steps per run
    "max_rows": 100_000,  # output rows per run
}

Gain = float | list[list[float]]


def _not_empty(name: str) -> str:
    # checked in Python: pydantic's own min_length converts the key to UTF-8 first, and a key
    # with a lone surrogate would then be refused as not text instead of as an unknown name
    if not name:
        raise PydanticCustomError("string_too_short", "String should have at least 1 character", {"min_length": 1})
    return name


#: a parameter's or a state value's name, as a key of ``params`` and ``initial`` (never empty)
Name = Annotated[str, AfterValidator(_not_empty), WithJsonSchema({"type": "string", "minLength": 1})]

#: the post-step projections a run can ask for (nmkane_core.integrate.projection.PRESETS)
ProjectionName = Literal["none", "blajer", "yoon"]
PROJECTIONS: tuple[str, ...] = typing.get_args(ProjectionName)

#: how a run ended (``summary.status``; nmkane_core.run.endings)
RunStatus = Literal["ok", "event", "singular", "diverged", "drifted", "timeout", "failed"]

#: the constraint solves a run can ask for (docs/closed-loops.md)
SolveName = Literal["auto", "paper", "robust"]
SOLVES: tuple[str, ...] = typing.get_args(SolveName)


class RunSettings(BaseModel):
    """A run request. Names follow the CLI's options with underscores."""

    model_config = ConfigDict(
        extra="forbid",
        allow_inf_nan=False,
        json_schema_extra={"examples": [{"dt": 0.01, "t_final": 20}]},  # the catalogue's first system
    )

    system: str | None = Field(
        None,
        description="the name of a registered system: a built-in one or one loaded from a systems "
        "file (GET /api/systems lists them); default: the catalogue's first",
        min_length=1,
        max_length=64,
    )
    model: str | None = Field(
        None,
        description="the variant to run, for a system whose variants are models "
        "(GET /api/systems lists each system's); default: the system's first",
        min_length=1,
        max_length=64,
    )
    formulation: str | None = Field(
        None,
        description="the variant to run, for a system whose variants are "
        "formulations (GET /api/systems lists each system's); default: the system's first",
        min_length=1,
        max_length=64,
    )
    gamma: Gain | None = Field(
        None,
        description="Γ for nonholonomic constraints (104): a scalar (Γ·I) or a matrix; stabilizing gains are negative",
    )
    gamma1: Gain | None = Field(
        None, description="Γ1 for holonomic constraints (112), s⁻¹: a scalar (Γ1·I) or a matrix; e.g. -20"
    )
    gamma2: Gain | None = Field(
        None, description="Γ2 for holonomic constraints (112), s⁻²: a scalar (Γ2·I) or a matrix; e.g. -100"
    )
    projection: ProjectionName | None = Field(
        None,
        description="post-step constraint correction (geometric elimination): none | blajer "
        "(Euclidean weight, energy restored) | yoon (kinetic-energy weight); see nmkane_core.integrate.projection; "
        "default: the system's (none for most; yoon for mechanisms that pass singular positions and for "
        "redundant constraint equations)",
    )
    singular_projection: bool = Field(
        True,
        description="without a projection, still project (yoon: the mass metric) each step that comes near a "
        "singular position of the constraints (a row of J shorter than 1e-2 of the longest), where the equations "
        "amplify any drift off the branch; summary.robust_solve counts them (near_singular_projections)",
    )
    solve: SolveName | None = Field(
        None,
        description="the constraint solve of a model with constraints: auto (the declared partition's "
        "T u̇ = V̂ where its J2 is well-conditioned, another partition or the rank-robust solve elsewhere) | "
        "paper (the declared partition only: a singular J2 ends the run singular) | robust (Gauss's "
        "principle in the mass metric everywhere); default: the system's (auto; paper for the paper's "
        "two examples, whose claims are about it)",
    )
    projection_weight: Literal["identity", "mass"] | None = Field(
        None, description="override the projection's weighting matrix W"
    )
    projection_iterations: int | None = Field(
        None, ge=1, le=20, description="override: Newton iterations of the position correction (1 = one-shot)"
    )
    projection_jacobian: Literal["updated", "frozen"] | None = Field(
        None, description="override: position Jacobian updated each iteration or frozen at the uncorrected point"
    )
    projection_energy: bool | None = Field(
        None, description="override: rescale the speeds to restore the initial energy after the correction"
    )
    integrator: str | None = Field(
        None,
        description="the integrator, by name (GET /api/systems lists them: fixed-step and adaptive "
        "Runge–Kutta tableaux, scipy's solvers); default: the system's",
        max_length=64,
    )
    dt: float | None = Field(
        None,
        ge=LIMITS["min_dt"],
        le=LIMITS["max_dt"],
        json_schema_extra={"unit": "s"},
        description="the step, s, of a fixed-step method (rk4, kutta-merson); the first step "
        "tried by an adaptive one (kutta-merson-adaptive, rk45, dop853, radau), whose steps "
        "then follow rtol and atol; default: the system's",
    )
    t_final: float | None = Field(
        None,
        gt=0,
        le=LIMITS["max_t_final"],
        json_schema_extra={"unit": "s"},
        description="final time, s; default: the system's",
    )
    every: int | None = Field(
        None,
        ge=1,
        le=LIMITS["max_steps"],
        description="keep every k-th step in the output (maxima use every step); unset: every step, or, for a "
        "fixed-step run with more steps than the output row cap, the smallest k that keeps it within the cap "
        "(said in the summary's warnings)",
    )
    output_times: list[float] | None = Field(
        None,
        min_length=1,
        max_length=LIMITS["max_rows"],
        description="report the state at these times only (s; increasing, within [0, t_final]), like scipy's "
        "t_eval: each computed by the run's method stepping from the output row before it, to the integrator's "
        "accuracy (every then only thins what is kept in between); the summary's maxima still cover every step",
    )
    stop_at: list[Name] | None = Field(
        None,
        description="the declared events that end the run at their first rising crossing (summary.event); [] none: "
        "every crossing is only recorded (summary.crossings) and the run goes on; unset: the system's stop_events "
        "(all its events unless it says otherwise)",
    )
    rtol: float = Field(1e-10, ge=1e-14, le=0.1, description="relative tolerance (adaptive methods)")
    atol: float = Field(1e-12, gt=0, le=1.0, description="absolute tolerance (adaptive methods)")
    rcond_min: float = Field(
        1e-10,
        ge=0,
        le=0.1,
        description="J2 or T with a pivot-ratio reciprocal condition, or a varying kinematics' C with an estimate, "
        "below this stops the run with status 'singular'",
    )
    max_energy_drift: float | None = Field(
        None,
        gt=0,
        description="stop the run (status 'drifted') where |E − E0| exceeds this, J; unset: 10⁶ times the "
        "initial energy scale max(|E0|, ½u₀ᵀQu₀) — a bound only a blow-up reaches (none when both are 0 or the "
        "model declares no energy); the bound used is in the summary's bounds",
    )
    max_violation: float | None = Field(
        None,
        gt=0,
        description="stop the run (status 'drifted') where a reported constraint violation |φ_i| or |ψ_i| "
        "exceeds this, in the constraint's own unit; unset: no bound",
    )
    switching: bool = Field(
        True,
        description="near a singular J2 or T, continue with an equivalent "
        "constraint model declared by the system and switch back afterwards",
    )
    rcond_switch: float = Field(
        1e-2,
        ge=0,
        le=0.5,
        description="reciprocal-condition estimate of J2 or T at which the "
        "run switches to an equivalent model (when the system declares one)",
    )
    constraint_forces: bool = Field(
        True,
        description="report the constraint forces F_c = Q u̇ − P (by speed) and the multipliers λ "
        "with F_c = Jᵀλ (by constraint) of every output row; false leaves them out (a few per cent "
        "of a run's time)",
    )
    project_initial: bool = Field(
        False,
        description="move a full initial state that violates the "
        "constraints onto the constraint manifold (the correction is reported) "
        "instead of refusing it",
    )
    error_estimate: bool = Field(
        False,
        description="estimate the run's global error: run it again with the same settings at half the step "
        "(fixed-step methods) or a tenth of rtol and atol (adaptive ones) and report the largest difference of "
        "each state at the run's output times (summary.error_estimate); costs a second run (2× the steps; 1.3–1.8× "
        "for an adaptive method), within the same time limit",
    )
    params: dict[Name, float] = Field(
        default_factory=dict,
        description="physical parameters by name; the system's "
        "defaults for those left out (names, ranges and units: GET /api/systems)",
    )
    initial: dict[Name, float] = Field(
        default_factory=dict,
        description="initial values: independent ones (the rest is completed) or a full consistent state",
    )


#: annotated-types bounds: (attribute, a lower bound?, included?)
_BOUNDS = (("ge", True, True), ("gt", True, False), ("le", False, True), ("lt", False, False))


def field_range(name: str) -> tuple[float, bool, float, bool, str] | None:
    """(low, low included, high, high included, unit) of a numeric :class:`RunSettings` field
    (from its declaration: ``ge``/``gt``/``le``/``lt``), or None when it declares no range."""
    info = RunSettings.model_fields[name]
    lo, lo_in, hi, hi_in, found = -math.inf, False, math.inf, False, False
    for m in info.metadata:
        for attr, is_low, included in _BOUNDS:
            v = getattr(m, attr, None)
            if v is not None:
                found = True
                if is_low:
                    lo, lo_in = float(v), included
                else:
                    hi, hi_in = float(v), included
    if not found:
        return None
    extra = info.json_schema_extra if isinstance(info.json_schema_extra, dict) else {}
    return lo, lo_in, hi, hi_in, str(extra.get("unit", ""))


def allowed(name: str) -> str:
    """What a numeric :class:`RunSettings` field allows, as every face says it:
    ``a finite number in [1e-07, 10] s``, ``an integer in [1, 50000000]``."""
    rng = field_range(name)
    integer = RunSettings.model_fields[name].annotation in (int, int | None)
    what = "an integer" if integer else "a finite number"
    if rng is None:
        return what
    lo, lo_in, hi, hi_in, unit = rng
    text = f"{what} in {'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"
    return text + (f" {unit}" if unit else "")


class Switch(BaseModel):
    t: float
    from_: str = Field(alias="from")
    to: str
    rcond: float
    model_config = ConfigDict(populate_by_name=True)


class PartitionUsed(BaseModel):
    """The partition a run started with: which speeds are independent, which coordinates are
    solved from the holonomic constraints, and whether the model declared it or the library
    picked it (Gaussian elimination with complete pivoting on J and ∂ψ/∂q at the system's
    default state).  A rank-robust solve may change it during the run (``switches``)."""

    u_independent: list[str] = Field(description="the independent speeds u_I")
    q_dependent: list[str] = Field(
        description="the coordinates solved from ψ = 0 (empty: none, or no holonomic constraint)"
    )
    chosen: Literal["declared", "pivoting"] = Field(
        description="declared by the model (u_independent, q_dependent), or picked by pivoting at the default state"
    )


class Event(BaseModel):
    """The event that ended a run (a system's declared events, nmkane_core.run.events)."""

    name: str = Field(description="the event's name, as the system declares it")
    t: float = Field(description="when it fired, s (located to the integrator's accuracy)")


class Crossing(BaseModel):
    """A crossing of a declared event's zero (nmkane_core.run.events)."""

    name: str = Field(description="the event's name, as the system declares it")
    t: float = Field(description="when, s (located to the integrator's accuracy)")
    direction: Literal["rising", "falling"] = Field(
        description="rising: from negative to ≥ 0 (the event fires); falling: back below 0"
    )


class ErrorEstimate(BaseModel):
    """A run's estimated global error (``error_estimate``, nmkane_core.run.accuracy): the run repeated with
    the same settings, refined, and the largest difference of each state between the two at the run's
    output times.  Without numbers (``max_abs`` null) when either run did not reach its end; ``message``
    says why."""

    method: Literal["half step", "tolerance / 10"] = Field(
        description="how the second run was refined: half step (fixed-step methods, dt/2 with every × 2: the "
        "same output times) or tolerance / 10 (adaptive methods: rtol/10, atol/10, its states interpolated to "
        "the run's times)"
    )
    refined: dict[str, float] = Field(description="the settings of the refined run that differ from the run's")
    refined_status: RunStatus | None = Field(
        None, description="how the refined run ended (null: it was not run, message says why)"
    )
    message: str = Field(description="what was compared, or why there are no numbers")
    rows: int = Field(0, description="the output rows compared")
    order: int | None = Field(None, description="the order p of a fixed-step method (Richardson's factor)")
    max_abs: dict[str, float] | None = Field(
        None,
        description="the largest |x − x_refined| of each state and output over the rows compared: the estimated "
        "global error of the run (null: no estimate)",
    )
    richardson: dict[str, float] | None = Field(
        None,
        description="fixed-step methods: max_abs × 2^p/(2^p − 1), the estimate of the error itself when the "
        "error is C h^p (null: adaptive methods, or no estimate)",
    )
    steps: int = Field(0, description="steps of the refined run")
    wall_time_s: float = Field(0.0, description="integration wall time of the refined run, s")


class RunSummary(BaseModel):
    status: RunStatus
    message: str
    steps: int
    rhs_evals: int
    wall_time_s: float = Field(description="integration wall time, s")
    kernel_load_s: float = Field(0.0, description="time to load (or first compile) the kernel, s")
    kernel_tier: Literal["compiled", "interpreted"] = Field(
        "compiled",
        description="how the loop ran: always compiled (the one compiled core; 'interpreted' was a first tier "
        "of earlier versions, kept in the schema so that their stored runs still validate)",
    )
    t_end: float
    max_abs_violation: dict[str, float]
    max_abs_energy_drift: float | None
    final_energy_drift: float | None
    max_abs_multiplier: dict[str, float] = Field(
        default_factory=dict, description="largest |λ| of each constraint over the output rows (empty: not asked for)"
    )
    max_abs_point_force: dict[str, float] = Field(
        default_factory=dict,
        description="largest magnitude |R| of each physical force the system declares at a point, over the output "
        "rows (empty: none declared, or not asked for)",
    )
    min_rcond: dict[str, float] = Field(
        default_factory=dict,
        description="smallest reciprocal condition estimate of J2 and T, and of the kinematics' C where it varies "
        "(key C: the volume of its rows scaled to unit length; absent where C is constant)",
    )
    warnings: list[str] = Field(default_factory=list)
    initial_correction: dict[str, float] = Field(
        default_factory=dict, description="change made by project_initial, per state"
    )
    switches: list[Switch] = Field(default_factory=list)
    robust_solve: dict[str, Any] | None = Field(
        None,
        description="what the rank-robust constraint solve did (models whose kernel has it): evaluations that "
        "used it, its smallest kept pivot and rank, the largest kinetic-energy share of a projection's speed "
        "correction, changes of solve beyond those listed in switches; null for the paper's solve on a declared "
        "partition",
    )
    bounds: dict[str, float | None] | None = Field(
        None,
        description="the bounds past which the run stops with status 'drifted': energy_drift (|E − E0|, J) and "
        "violation (null: none)",
    )
    event: Event | None = Field(None, description="the declared event that ended the run (status 'event'), if any")
    crossings: list[Crossing] = Field(
        default_factory=list,
        description="every crossing of the system's declared events up to the run's end, in time order (the first "
        "1,000)",
    )
    crossings_not_listed: int = Field(0, description="crossings beyond those listed")
    partition: PartitionUsed | None = Field(None, description="the partition the run started with")
    error_estimate: ErrorEstimate | None = Field(
        None, description="the estimated global error, when the run asked for it (error_estimate); else null"
    )


class RunResult(BaseModel):
    """The run result document: times, states, energy, violations and the summary."""

    id: str | None = None
    system: str
    settings: dict
    t: list[float]
    state: dict[str, list[float]]
    energy: list[float] | None
    violation: dict[str, list[float]]
    constraint_forces: dict[str, list[float]] = Field(
        default_factory=dict,
        description="the generalized constraint force F_c = Q u̇ − P of each speed (Kane's generalized forces of the "
        "constraints, with the run's u̇: stabilization included), one value per output row",
    )
    multipliers: dict[str, list[float]] = Field(
        default_factory=dict,
        description="λ of each constraint with F_c = Jᵀλ, J = ∂[φ; ψ̇]/∂u (depends on how a constraint is "
        "written; F_c does not), one value per output row",
    )
    point_forces: dict[str, list[float]] = Field(
        default_factory=dict,
        description="the physical forces the system declares at points (a contact force, a blade force, a thread "
        "tension), by NAME.LABEL (e.g. contact.normal): each force's components along its declared axes, N, one value "
        "per output row; which forces, where and by which route: GET /api/systems",
    )
    summary: RunSummary
