"""Named systems: a public name, parameters with defaults and ranges, and variants.

A :class:`System` gathers what users choose by name (``appell-hamel``,
``sliding-particle``): its physical parameters, its reported state, its default initial
state and its *variants* — equivalent models of the same mechanism (the Appell–Hamel
constraint models ``nonlinear``/``linear``, the sliding particle's ``nonminimal`` and
``minimal`` formulations).  Each variant is a :class:`~nmkane_core.model.MechanicalModel`
built lazily (sympy work) and cached, and derived once.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Callable, Mapping

import threading
from typing import TYPE_CHECKING

from .errors import InputError

if TYPE_CHECKING:  # sympy is imported only when a model is actually built
    from .derivation import Derivation
    from .info import ModelInfo
    from .model import MechanicalModel

__all__ = ["Parameter", "System", "register", "get_system", "system_names"]


@dataclass(frozen=True)
class Parameter:
    """A physical parameter: default value, allowed open/closed range, unit, meaning."""

    name: str
    default: float
    min: float
    max: float
    unit: str = ""
    description: str = ""
    min_inclusive: bool = False

    def check(self, value, field_path: str) -> float:
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(field_path, value, self.allowed(), "not a number") from None
        if not math.isfinite(v):
            raise InputError(field_path, value, self.allowed(), "not finite")
        low_ok = v >= self.min if self.min_inclusive else v > self.min
        if not low_ok or v > self.max:
            raise InputError(field_path, value, self.allowed(), "out of range")
        return v

    def allowed(self) -> str:
        lo = "[" if self.min_inclusive else "("
        return f"a finite number in {lo}{self.min:g}, {self.max:g}]" + (f" {self.unit}" if self.unit else "")


@dataclass
class System:
    """A named mechanical system with equivalent variants (models/formulations)."""

    name: str
    title: str
    option: str                                   # "model" or "formulation"
    variants: Mapping[str, Callable[[], MechanicalModel]]
    default_variant: str
    parameters: tuple[Parameter, ...]
    coordinates: tuple[str, ...]
    speeds: tuple[str, ...]
    default_initial: Mapping[str, float]
    completion_variant: str | None = None         # variant used to complete/check initial states
    equivalents: Mapping[str, tuple[str, ...]] = field(default_factory=dict)  # switching targets
    # variant -> where its J2 or T is singular, appended to the message of a run stopped there
    singular_hints: Mapping[str, str] = field(default_factory=dict)
    independent: tuple[str, ...] = ()             # names a user sets; the rest are completed
    default_dt: float = 0.01
    default_t_final: float = 20.0
    default_integrator: str = "kutta-merson"
    default_gamma: float = 0.0
    default_gamma1: float = 0.0
    default_gamma2: float = 0.0
    description: str = ""
    source_files: tuple[str, ...] = ()           # files defining the variants (kernel cache key)
    _models: dict = field(default_factory=dict, repr=False)
    _derivations: dict = field(default_factory=dict, repr=False)
    _kernels: dict = field(default_factory=dict, repr=False)
    _lock: threading.RLock = field(default_factory=threading.RLock, repr=False)

    @property
    def state_names(self) -> tuple[str, ...]:
        return self.coordinates + self.speeds

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
            raise InputError(field_path or self.option, variant, " | ".join(self.variants),
                             f"unknown {self.option} of {self.name}")
        return variant

    def model(self, variant: str | None = None) -> "MechanicalModel":
        """The symbolic description of a variant (built once; needs sympy)."""
        variant = self.check_variant(variant)
        with self._lock:
            if variant not in self._models:
                self._models[variant] = self.variants[variant]()
            return self._models[variant]

    def derivation(self, variant: str | None = None) -> "Derivation":
        """The paper's procedure applied to a variant (symbolic, once)."""
        from .derivation import derive

        variant = self.check_variant(variant)
        with self._lock:
            if variant not in self._derivations:
                self._derivations[variant] = derive(self.model(variant))
            return self._derivations[variant]

    def kernel(self, variant: str | None = None):
        """(compiled kernel module, :class:`ModelInfo`) of a variant.

        Loaded from the on-disk cache when the files that define the system are unchanged
        (no sympy work at all), otherwise derived, generated, compiled and cached.
        """
        from .codegen import fingerprint, kernel

        variant = self.check_variant(variant)
        with self._lock:
            if variant not in self._kernels:
                fp = fingerprint(self.name, variant, self.source_files)
                self._kernels[variant] = kernel(fp, lambda: self.derivation(variant))
            return self._kernels[variant]

    def kernel_key(self, variant: str | None = None) -> str | None:
        """A key that changes whenever the variant's compiled kernel would (None: not cached).

        Other caches derived from a model (the web app's rendered matrices) key on it."""
        from .codegen import fingerprint

        return fingerprint(self.name, self.check_variant(variant), self.source_files)

    def info(self, variant: str | None = None) -> "ModelInfo":
        return self.kernel(variant)[1]

    def resolve_params(self, given: Mapping[str, object] | None, field_path: str = "params") -> dict[str, float]:
        """Defaults filled in, every value checked against its range."""
        given = dict(given or {})
        unknown = sorted(set(given) - set(self.param_names))
        if unknown:
            raise InputError(f"{field_path}.{unknown[0]}", given[unknown[0]],
                             f"parameters of {self.name}: {', '.join(self.param_names)}",
                             "unknown parameter")
        return {p.name: p.check(given.get(p.name, p.default), f"{field_path}.{p.name}")
                for p in self.parameters}

    def constraint_names(self, variant: str | None = None) -> tuple[str, ...]:
        """Names of the reported violations: the constraints, then any monitors."""
        return self.info(variant).viol_names


_REGISTRY: dict[str, Callable[[], System]] = {}


def register(name: str):
    """Decorator: register a zero-argument factory of a :class:`System` under ``name``."""
    def deco(factory):
        _REGISTRY[name] = factory
        return factory
    return deco


def system_names() -> tuple[str, ...]:
    _load_builtin()
    return tuple(_REGISTRY)


@lru_cache(maxsize=None)
def _get(name: str) -> System:
    return _REGISTRY[name]()


def get_system(name: str, field_path: str = "system") -> System:
    _load_builtin()
    if name not in _REGISTRY:
        raise InputError(field_path, name, " | ".join(_REGISTRY), "unknown system")
    return _get(name)


def _load_builtin() -> None:
    from . import systems  # noqa: F401  (registers the paper's examples)
