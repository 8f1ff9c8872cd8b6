"""Errors that nmkane reports to people (CLI, REST, web) rather than tracebacks."""

from __future__ import annotations


class NmkaneError(Exception):
    """Base class of every error nmkane raises on purpose."""


class InputError(NmkaneError, ValueError):
    """Bad input: names the field, the value given and what is allowed.

    The CLI prints ``str(err)`` on one line and exits 2; the REST service answers 422 with
    ``field``, ``value`` and ``allowed`` in the body.

    Parameters
    ----------
    field : str
        Where: a settings field, ``params.NAME``, ``state.NAME``, an option.
    value : object
        The value given.
    allowed : str
        What is allowed, in words (``"a number in (0, 1e3]"``).
    reason : str, optional
        Why the value was refused, when "not allowed" is not enough.
    """

    def __init__(self, field: str, value: object, allowed: str, reason: str | None = None):
        self.field = field
        self.value = value
        self.allowed = allowed
        self.reason = reason
        text = f"{field}: got {value!r}"
        if reason:
            text += f" ({reason})"
        text += f"; allowed: {allowed}"
        super().__init__(text)


class InconsistentStateError(InputError):
    """An initial state that violates the constraints beyond the tolerance."""


class ConvergenceError(NmkaneError):
    """A Newton iteration (state completion, projection) that did not converge."""


class NotDefined(NmkaneError):
    """A matrix of the paper's procedure that a model does not have (A = −J2⁻¹J1 and what is
    built on it, for constraints that are redundant: no partition makes J2 square and
    invertible; its runs use the rank-robust solve)."""


class SingularMatrix(ArithmeticError):
    """J2, T or the kinematics' C is singular or ill-conditioned at a state (``matrix``, ``rcond``, ``t``)."""

    def __init__(self, matrix: str, rcond: float, t: float):
        self.matrix, self.rcond, self.t = matrix, rcond, t
        super().__init__(
            f"{matrix} is singular or ill-conditioned at t = {t:.6g} s (reciprocal condition estimate {rcond:.3g})"
        )
