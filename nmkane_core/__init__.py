"""nmkane_core — nonminimal Kane's equations (Bajodah, Hodges & Chen 2005).

Describe a system with sympy (:class:`MechanicalModel`), derive the paper's matrices
once (:func:`derive`), and simulate with compiled kernels (:func:`simulate`).
"""

from typing import TYPE_CHECKING

# Every name is bound on first use (PEP 562): ``import nmkane_core.kernel.…`` — what every
# generated kernel does, in the background compiling child too — costs no pydantic, no
# registry and no sympy (0.84 s of a child's start before it could compile).
_LAZY = {
    "Parameter": "declare.system",
    "System": "declare.system",
    "ConvergenceError": "errors",
    "InconsistentStateError": "errors",
    "InputError": "errors",
    "NmkaneError": "errors",
    "get_system": "run.registry",
    "register": "run.registry",
    "system_names": "run.registry",
    "unregister": "run.registry",
    "resolve": "run.simulate",
    "simulate": "run.simulate",
    "simulate_many": "run.simulate",
    "RunResult": "schema",
    "RunSettings": "schema",
    "Derivation": "symbolic.derivation",
    "derive": "symbolic.derivation",
    "MechanicalModel": "symbolic.model",
    "plain_symbols": "symbolic.model",
    "accelerations": "analysis.at_state",
    "linearize": "analysis.at_state",
    "load_systems": "run.plugins",
    "show": "run.show",
}

if TYPE_CHECKING:  # what the names are, for the type checker
    from .analysis.at_state import accelerations, linearize
    from .declare.system import Parameter, System
    from .errors import ConvergenceError, InconsistentStateError, InputError, NmkaneError
    from .run.plugins import load_systems
    from .run.registry import get_system, register, system_names, unregister
    from .run.show import show
    from .run.simulate import resolve, simulate, simulate_many
    from .schema import RunResult, RunSettings
    from .symbolic.derivation import Derivation, derive
    from .symbolic.model import MechanicalModel, plain_symbols


def __getattr__(name):  # PEP 562
    if name in _LAZY:
        import importlib

        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value  # bound: the next use is a plain lookup
        return value
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
