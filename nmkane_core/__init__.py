"""nmkane_core — nonminimal Kane's equations (Bajodah, Hodges & Chen 2005).

Describe a system with sympy (:class:`MechanicalModel`), derive the paper's matrices
once (:func:`derive`), and simulate with compiled kernels (:func:`simulate`).
"""

from .derivation import Derivation, derive
from .errors import ConvergenceError, InconsistentStateError, InputError, NmkaneError
from .model import MechanicalModel, plain_symbols
from .system import Parameter, System, get_system, register, system_names

__all__ = [
    "ConvergenceError", "Derivation", "InconsistentStateError", "InputError", "MechanicalModel",
    "NmkaneError", "Parameter", "System", "derive", "get_system", "plain_symbols", "register",
    "system_names",
]
__version__ = "0.1.0"
