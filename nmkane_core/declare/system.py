"""Named systems: what a user declares once, bound by name, checked when registered.

A :class:`System` gathers what users choose by name (the names of the catalogue): its
physical parameters (keyed by the model's own symbols or their names), its default initial
state and its *variants* — equivalent models of the same mechanism (two constraint models
of one mechanism, ``nonlinear``/``linear``, as in the paper's Example 1; a ``nonminimal``
and a ``minimal`` formulation, as in its Example 2).  A system with one variant gives just its model (or a function
that builds it).  Everything else is taken from the model: coordinates and speeds from
``q`` and ``u``, the independent values a user sets from ``u_independent`` and the
coordinates not solved from holonomic constraints.

A ``System`` is the declaration and nothing else: constructing one checks what can be checked
without the models (names, numbers, the variants named in options).  What is built from it —
each variant's :class:`~nmkane_core.symbolic.model.MechanicalModel`, derivation and compiled
kernel — lives in the kernel layer (:func:`nmkane_core.kernel.built.built`), and
:func:`nmkane_core.run.registry.register` checks the declaration against the models (parameter
names, the default initial state) without changing it, so a mistake is reported when a system
is registered, not at its first run.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from ..errors import InputError
from ..schema import LIMITS, PROJECTIONS, SOLVES, allowed, field_range
from .parameter import Parameter

if TYPE_CHECKING:
    from ..symbolic.model import MechanicalModel

__all__ = ["Parameter", "System"]

SINGLE_VARIANT = "default"  # the variant name of a system declared with one model


def _name(key: Any) -> str:
    """A symbol's name (sympy Symbol or dynamicsymbol) or a plain string key."""
    if isinstance(key, str):
        return key
    text = str(getattr(key, "name", key))
    return text.removesuffix("(t)")


def _as_factory(v: Any) -> Callable[[], MechanicalModel]:
    if callable(v) and not hasattr(v, "q"):
        return v
    return lambda: v


SHOWCASE_NUMBERS = ("gamma", "gamma1", "gamma2", "dt", "t_final", "speed")


@dataclass
class System:
    """A named mechanical system: one model, or equivalent variants of it.

    Parameters
    ----------
    name:
        The public name (lower case with hyphens, e.g. ``my-cart``): CLI argument, REST ``system`` field.
    variants:
        A :class:`MechanicalModel`, a zero-argument function building one, or a mapping
        variant name → model or function (equivalent models of one mechanism).
    parameters:
        ``{symbol or name: Parameter(default, min, max, unit, description)}`` for every
        parameter symbol of the models (checked by name when registered).
    default_initial:
        ``{symbol or name: value}``: the independent values (the dependent ones are
        completed from the constraints when the system is checked; values given for
        dependent ones are the starting guesses of that completion, which pick the branch
        of a constraint nonlinear in the speeds; missing values are 0) or a full
        consistent state.
    title, description:
        Shown in the web app and ``GET /api/systems``.
    option:
        What the variants are called when there are several: ``"model"`` (CLI
        ``--model``, REST ``model``) or ``"formulation"``.
    default_variant, completion_variant:
        The variant run when none is chosen (default: the first), and the one whose
        constraints complete and check initial states (default: the default variant).
    equivalents:
        Variant → variants that describe the same motion, to switch to where the first is
        singular (a model whose J2 is singular where a wheel stops rolling, say, beside one that is not).
    singular_hints:
        Variant → a sentence appended to a ``singular`` run's message (why it happens).
    default_dt, default_t_final, default_integrator, default_gamma, default_gamma1, default_gamma2:
        Run settings used when a request leaves them out.
    default_projection:
        The post-step projection of runs that do not choose one (``none``, ``blajer``, ``yoon``,
        or ``auto``, the default: ``yoon`` for a model whose constraint equations are redundant
        — their rank below their number, which drift makes inconsistent — else ``none``): a
        mechanism that passes singular positions needs the mass-metric projection (``yoon``)
        to stay on its branch (docs/closed-loops.md §5); scipy integrators run without it.
    default_solve:
        The constraint solve of runs that do not choose one: ``"auto"`` (the default: the
        declared partition where its J2 is well-conditioned, another partition or the
        rank-robust solve elsewhere), ``"paper"`` (the declared partition only: a singular J2
        ends the run ``singular``; the paper's two examples, whose claims are about it) or
        ``"robust"``.
    visuals:
        A zero-argument function returning :class:`~nmkane_core.declare.visuals.Visuals` (shapes on
        frames and points, sympy expressions of the state and parameters), or None: the web
        app draws what a system declares (compiled once, see :mod:`nmkane_core.declare.visuals`).
    what_to_try:
        A short teaching paragraph: experiments worth making with this system.
    showcase:
        The settings a viewer (the web page) starts with where they differ from the run
        defaults above, e.g. a paper's figure: ``gamma``, ``gamma1``, ``gamma2``, ``dt``,
        ``t_final`` (numbers), ``variant``, ``integrator``, ``compare`` (the runs drawn as
        ghosts beside the shown one: ``"off"``, a variant name, ``"Γ = 0"`` or ``"all"``) and
        ``speed`` (playback).  Runs through the CLI and REST are not affected.
    forces:
        A function of the variant name (or of nothing) returning
        :class:`~nmkane_core.declare.forces.Forces`: where the constraint forces act (points,
        the frame of their components, sympy expressions of the state, the multipliers and the
        accelerations; compiled once, see :mod:`nmkane_core.declare.forces`), or None.  Runs
        then report the forces' components (``Run.point_forces``).
    events:
        A zero-argument function returning ``{name: expression}`` (sympy, of the state and
        parameters, negative in normal motion): a run ends with status ``"event"`` when one
        reaches zero (:mod:`nmkane_core.run.events`); every crossing is recorded.
    stop_events:
        The events that end a run (at their first rising crossing) when the run does not say
        (``RunSettings.stop_at``); None: all of them.
    initial_controls:
        ``{name: (min, max, label)}``: the initial values a user interface offers (sliders),
        with their ranges; empty: every independent value, ranges from the defaults.
    stability:
        A :class:`~nmkane_core.declare.stability.Stability`: what ``nmkane stability`` and the web
        app's eigenvalue plot sweep (the value, the state at it, the values linearized).
    source_files:
        Extra files the models are built from.  The files that define the variant
        functions are found by themselves; list helper modules they import, so that a
        change there also invalidates the cached kernel.
    """

    name: str
    variants: Any
    parameters: Any = ()
    default_initial: Mapping[Any, float] = field(default_factory=dict)
    title: str = ""
    description: str = ""
    option: str = "model"
    default_variant: str = ""  # "": the first variant
    completion_variant: str = ""  # "": the default variant
    equivalents: Mapping[str, tuple[str, ...]] = field(default_factory=dict)
    singular_hints: Mapping[str, str] = field(default_factory=dict)
    default_dt: float = 0.01
    default_t_final: float = 20.0
    default_integrator: str = "kutta-merson"
    default_gamma: float = 0.0
    default_gamma1: float = 0.0
    default_gamma2: float = 0.0
    default_projection: str = "auto"
    default_solve: str = "auto"
    source_files: tuple[str, ...] = ()
    visuals: Callable[[], Any] | None = None
    what_to_try: str = ""
    showcase: Mapping[str, Any] = field(default_factory=dict)
    events: Callable[[], Any] | None = None
    stop_events: tuple[str, ...] | None = None
    forces: Callable[..., Any] | None = None
    stability: Any = None
    initial_controls: Mapping[str, tuple[float, float, str]] = field(default_factory=dict)
    given_models: dict = field(default_factory=dict, init=False, repr=False)  # variants given as objects

    def __post_init__(self):
        if not isinstance(self.name, str) or not self.name.strip():
            raise InputError("System.name", self.name, "a non-empty string such as 'my-cart'", "no name")
        raw = self.variants
        if isinstance(raw, Mapping):
            if not raw:
                raise InputError(f"{self.name}: variants", raw, "at least one model", "empty")
            self.variants = {str(k): _as_factory(v) for k, v in raw.items()}
        else:
            self.variants = {SINGLE_VARIANT: _as_factory(raw)}
        self.given_models = {
            k: v for k, v in (raw.items() if isinstance(raw, Mapping) else [(SINGLE_VARIANT, raw)]) if hasattr(v, "q")
        }
        if self.option not in ("model", "formulation"):
            raise InputError(f"{self.name}: option", self.option, "model | formulation", "unknown")
        names = " | ".join(self.variants)
        self.default_variant = self.default_variant or next(iter(self.variants))
        self.completion_variant = self.completion_variant or self.default_variant
        for label in ("default_variant", "completion_variant"):
            if getattr(self, label) not in self.variants:
                raise InputError(f"{self.name}: {label}", getattr(self, label), names, "not a variant")
        for v, alts in self.equivalents.items():
            for a in (v, *alts):
                if a not in self.variants:
                    raise InputError(f"{self.name}: equivalents", a, names, "not a variant")
        self.parameters = self._bind_parameters(self.parameters)
        self.default_initial = {
            _name(k): self._finite(f"default_initial.{_name(k)}", v) for k, v in dict(self.default_initial).items()
        }
        for label, setting in (("default_dt", "dt"), ("default_t_final", "t_final")):
            self._in_range(label, setting)
        if self.default_projection not in (*PROJECTIONS, "auto"):
            raise InputError(
                f"{self.name}: default_projection",
                self.default_projection,
                " | ".join((*PROJECTIONS, "auto")),
                "unknown",
            )
        if self.default_solve not in SOLVES:
            raise InputError(f"{self.name}: default_solve", self.default_solve, " | ".join(SOLVES), "unknown")
        for gain in ("default_gamma", "default_gamma1", "default_gamma2"):
            g = self._finite(gain, getattr(self, gain))
            if abs(g) > LIMITS["max_gain"]:
                raise InputError(f"{self.name}: {gain}", g, f"|Γ| ≤ {LIMITS['max_gain']:g}", "out of range")
        if self.forces is not None and not callable(self.forces):
            what = type(self.forces).__name__
            raise InputError(f"{self.name}: forces", what, "a function returning Forces, or None", "not callable")
        self.showcase = dict(self.showcase)
        for k, v in self.showcase.items():
            if k in SHOWCASE_NUMBERS:
                self._finite(f"showcase.{k}", v)
            elif k not in ("variant", "integrator", "compare"):
                allowed = " | ".join((*SHOWCASE_NUMBERS, "variant", "integrator", "compare"))
                raise InputError(f"{self.name}: showcase", k, allowed, "unknown setting")
        if self.showcase.get("variant", self.default_variant) not in self.variants:
            raise InputError(f"{self.name}: showcase.variant", self.showcase["variant"], names, "not a variant")

    def _in_range(self, label: str, setting: str) -> None:
        """A default run setting within the range the run settings declare for it."""
        v = getattr(self, label)
        rng = field_range(setting)
        assert rng is not None
        lo, lo_in, hi, hi_in, _ = rng
        ok = (
            isinstance(v, (int, float))
            and not isinstance(v, bool)
            and math.isfinite(v)
            and (v >= lo if lo_in else v > lo)
            and (v <= hi if hi_in else v < hi)
        )
        if not ok:
            raise InputError(f"{self.name}: {label}", v, allowed(setting), "out of range")

    def _finite(self, field_path: str, v) -> float:
        try:
            x = float(v)
        except (TypeError, ValueError):
            raise InputError(f"{self.name}: {field_path}", v, "a finite number", "not a number") from None
        if not math.isfinite(x):
            raise InputError(f"{self.name}: {field_path}", v, "a finite number", "not finite")
        return x

    def _bind_parameters(self, declared) -> tuple[Parameter, ...]:
        if isinstance(declared, Mapping):
            items = [(_name(k), p) for k, p in declared.items()]
        else:
            items = [(p.name, p) for p in declared]
        out = []
        for key, p in items:
            if not isinstance(p, Parameter):
                raise InputError(
                    f"{self.name}: parameters.{key}",
                    p,
                    "Parameter(default, min, max, unit, description)",
                    "not a Parameter",
                )
            if not key:
                raise InputError(
                    f"{self.name}: parameters",
                    p,
                    "parameters keyed by their symbols or names",
                    "a Parameter without a name",
                )
            if p.name and p.name != key:
                raise InputError(
                    f"{self.name}: parameters.{key}",
                    p.name,
                    f"the key it is declared under ({key})",
                    "two names for one parameter",
                )
            out.append(replace(p, name=key))
        seen = [p.name for p in out]
        dup = {n for n in seen if seen.count(n) > 1}
        if dup:
            raise InputError(f"{self.name}: parameters", sorted(dup), "each parameter once", "declared twice")
        return tuple(out)

    # ------------------------------------------------------------------ names, from the models
    @property
    def variant_names(self) -> tuple[str, ...]:
        return tuple(self.variants)

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    def parameter(self, name: str) -> Parameter:
        for p in self.parameters:
            if p.name == name:
                return p
        raise KeyError(name)

    def check_variant(self, variant: str | None, field_path: str | None = None) -> str:
        if variant is None:
            return self.default_variant
        if variant not in self.variants:
            raise InputError(
                field_path or self.option, variant, " | ".join(self.variants), f"unknown {self.option} of {self.name}"
            )
        return variant

    # ------------------------------------------------------------------ values
    def resolve_params(self, given: Mapping[str, object] | None, field_path: str = "params") -> dict[str, float]:
        """Defaults filled in, every value checked against its range."""
        given = dict(given or {})
        unknown = sorted(set(given) - set(self.param_names))
        if unknown:
            raise InputError(
                f"{field_path}.{unknown[0]}",
                given[unknown[0]],
                f"parameters of {self.name}: {', '.join(self.param_names)}",
                "unknown parameter",
            )
        return {p.name: p.check(given.get(p.name, p.default), f"{field_path}.{p.name}") for p in self.parameters}
