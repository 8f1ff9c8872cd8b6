"""nmkane_core — nonminimal Kane's equations (Bajodah, Hodges & Chen 2005).

Describe a system with sympy (:class:`MechanicalModel`), derive the paper's matrices
once (:func:`derive`), and simulate with compiled kernels (:func:`simulate`).
"""

from .declare.system import Parameter, System
from .errors import ConvergenceError, InconsistentStateError, InputError, NmkaneError
from .run.registry import get_system, register, system_names

# Bound eagerly (numpy and pydantic only): what every run needs.
from .run.simulate import resolve, simulate, simulate_many
from .schema import RunResult, RunSettings

_LAZY = {
    "Derivation": "symbolic.derivation",
    "derive": "symbolic.derivation",
    "MechanicalModel": "symbolic.model",
    "plain_symbols": "symbolic.model",
    "accelerations": "analysis.at_state",
    "linearize": "analysis.at_state",
    "load_systems": "run.plugins",
    "unregister": "run.registry",
    "show": "run.show",
}  # sympy is imported only when symbolic work is asked for


def __getattr__(name):  # PEP 562
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(name)


__all__ = [
    "ConvergenceError",
    "Derivation",
    "accelerations",
    "linearize",
    "load_systems",
    "unregister",
    "InconsistentStateError",
    "InputError",
    "MechanicalModel",
    "NmkaneError",
    "Parameter",
    "RunResult",
    "RunSettings",
    "System",
    "derive",
    "get_system",
    "plain_symbols",
    "register",
    "resolve",
    "simulate",
    "simulate_many",
    "show",
    "system_names",
]
__version__ = "0.1.0"
