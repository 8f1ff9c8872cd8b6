"""nmkane_core — nonminimal Kane's equations (Bajodah, Hodges & Chen 2005).

Describe a system with sympy (:class:`MechanicalModel`), derive the paper's matrices
once (:func:`derive`), and simulate with compiled kernels (:func:`simulate`).
"""

from .errors import ConvergenceError, InconsistentStateError, InputError, NmkaneError
from .registry import get_system, register, system_names
from .schema import RunResult, RunSettings

# Bound eagerly (numpy and pydantic only): the function ``simulate`` shares its name with
# its module, and once anything imports ``nmkane_core.simulate`` the import system sets
# that attribute of the package to the module — a lazy name would then hand users the
# module instead of the function.
from .simulate import resolve, simulate, simulate_many
from .system import Parameter, System

_LAZY = {
    "Derivation": "derivation",
    "derive": "derivation",
    "MechanicalModel": "model",
    "plain_symbols": "model",
    "accelerations": "analysis",
    "linearize": "analysis",
    "load_systems": "plugins",
    "unregister": "registry",
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
    "system_names",
]
__version__ = "0.1.0"
