"""How a run ended, as data: each loop status (and stop reason) with its summary status and message.

:data:`ENDINGS` maps ``(STATUS_* code, stop reason)`` — the stop reason being what ended a
run early between chunks (``"timeout"``, ``"cancelled"``, ``"max_steps"``, ``"max_rows"``) or
None — to an :class:`Ending`: the run's ``summary["status"]`` and a message template filled
from the run's facts (:func:`ending`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..kernel.constants import (
    KIN_STEP_CHANGE,
    ROBUST_LEAVE_KE,
    STATUS_C_SINGULAR,
    STATUS_C_UNRESOLVED,
    STATUS_DIVERGED,
    STATUS_DRIFTED,
    STATUS_FAILED,
    STATUS_INCONSISTENT,
    STATUS_J2_SINGULAR,
    STATUS_LEFT_CONSTRAINTS,
    STATUS_OK,
    STATUS_PROJECTION_FAILED,
    STATUS_Q_SINGULAR,
    STATUS_T_SINGULAR,
)

__all__ = ["ENDINGS", "OVERFLOW", "Ending", "ending"]

_UNDEFINED = (
    "a point where the model's expressions are not defined — a square root of a negative number, "
    "a zero denominator — e.g. the end of the branch of a constraint nonlinear in the speeds"
)


#: the cure of a singular kinematics, said once
_REGULAR = "coordinates regular there do not have it: a unit quaternion for a rotation, docs/your-own-system.md"


@dataclass(frozen=True)
class Ending:
    """A run's status and the message that says why (a ``str.format`` template of the facts:
    steps, method, t_final, t_end, matrix, rcond, rcond_c, rcond_min, projection, max_steps, max_rows)."""

    status: str
    message: str


_SINGULAR = Ending(
    "singular",
    "{matrix} became singular or ill-conditioned after t = {t_end:.6g} s (reciprocal condition estimate "
    "{rcond:.3g} ≤ rcond_min = {rcond_min:g}); the run stopped there and keeps the last good state",
)

ENDINGS: dict[tuple[int, str | None], Ending] = {
    (STATUS_OK, None): Ending("ok", "completed: {steps:,} steps of {method} to t = {t_final:g} s"),
    (STATUS_OK, "timeout"): Ending(
        "timeout", "stopped at t = {t_end:.6g} s: wall-time limit reached; results up to there are kept"
    ),
    (STATUS_OK, "cancelled"): Ending(
        "timeout", "stopped at t = {t_end:.6g} s: cancelled; results up to there are kept"
    ),
    (STATUS_J2_SINGULAR, None): _SINGULAR,
    (STATUS_T_SINGULAR, None): _SINGULAR,
    (STATUS_C_SINGULAR, None): Ending(
        "singular",
        "the kinematics q̇ = C(q) u + D became singular after t = {t_end:.6g} s (C's estimate {rcond_c:.3g} ≤ "
        "rcond_min = {rcond_min:g}): the coordinates degenerate there, as Euler angles do at gimbal lock; the run "
        "stopped there and keeps the last good state (" + _REGULAR + ")",
    ),
    (STATUS_C_UNRESOLVED, None): Ending(
        "singular",
        "the kinematics q̇ = C(q) u + D came near a singular configuration after t = {t_end:.6g} s (C's estimate "
        "{rcond_c:.3g}), faster than the step follows: within one step the estimate changed by more than "
        + f"{KIN_STEP_CHANGE:g}"
        + " of itself — the coordinates swing there (Euler angles near gimbal lock), and a step that misses the "
        "swing goes on with a wrong configuration; the run stopped and keeps the last good state (a smaller dt or an "
        "adaptive method follows the swing; " + _REGULAR + ")",
    ),
    (STATUS_DIVERGED, None): Ending(
        "diverged",
        "the state or its derivative stopped being finite after t = {t_end:.6g} s; the run stopped and keeps "
        "the last finite state (an unstable step: try a smaller dt or gains of smaller magnitude; or the motion "
        "reached " + _UNDEFINED + ")",
    ),
    (STATUS_DRIFTED, None): Ending(
        "drifted",
        "{drift} after t = {t_end:.6g} s, past the run's bound of {bound:.3g}; the run stopped there and keeps the "
        "last state within it (the motion blew up or left its branch: try a smaller dt, the projection, other "
        "gains; max_energy_drift and max_violation set the bounds)",
    ),
    (STATUS_INCONSISTENT, None): Ending(
        "singular",
        "the acceleration constraints are inconsistent after t = {t_end:.6g} s: rank {rank} of {m}, the dependent "
        "equations ({dropped}) miss by {residual:.3g} (relative) — the motion cannot continue on the constraints "
        "there (a lock-up, or a state the redundant equations disagree on); the run keeps the last good state",
    ),
    (STATUS_Q_SINGULAR, None): Ending(
        "singular",
        "Q, the mass matrix, is not positive definite after t = {t_end:.6g} s (its Cholesky factorization failed): "
        "the model's inertia degenerates there; the run keeps the last good state",
    ),
    (STATUS_LEFT_CONSTRAINTS, None): Ending(
        "singular",
        "the motion left the constraints after t = {t_end:.6g} s: {correction} carried {share:.3g} of the kinetic "
        "energy in one step (more than "
        + f"{ROBUST_LEAVE_KE:g}"
        + ") — near a singular position the equations amplify any drift off the branch; {cure}; the run keeps "
        "the last good state",
    ),
    (STATUS_PROJECTION_FAILED, None): Ending(
        "failed",
        "the {projection} projection met a singular correction matrix after t = {t_end:.6g} s; the run stopped there",
    ),
    (STATUS_FAILED, "max_steps"): Ending("failed", "the step budget ({max_steps:,}) was used up at t = {t_end:.6g} s"),
    (STATUS_FAILED, "max_rows"): Ending(
        "failed",
        "the output reached its limit of {max_rows:,} rows at t = {t_end:.6g} s (the step size kept "
        "shrinking — a singularity ahead? — or use a larger every); the rows up to there are kept",
    ),
    (STATUS_FAILED, None): Ending(
        "failed",
        "the step size fell below its minimum at t = {t_end:.6g} s: the solution cannot be continued there "
        "(a blow-up, or " + _UNDEFINED + "); the rows up to there are kept",
    ),
}

#: the energy, a violation or an output overflowed before the state did (the rows are cut)
OVERFLOW = Ending(
    "diverged",
    "the energy, a constraint violation or an output stopped being finite (overflow) after t = {t_end:.6g} s; "
    "the run stopped and keeps the rows up to there (try smaller initial speeds, a smaller dt or gains of "
    "smaller magnitude)",
)


def ending(code: int, stop: str | None, facts: dict, fail_msg: str | None = None, hint: str = "") -> tuple[str, str]:
    """(status, message) of a run that ended with loop status ``code`` and stop reason ``stop``.

    ``fail_msg`` (a driver's own account of a failure, e.g. scipy's) replaces the message of a
    failed run; ``hint`` (a system's singular hint) is appended to a singular run's."""
    found = ENDINGS.get((code, stop)) or ENDINGS.get((code, None)) or ENDINGS[(STATUS_FAILED, None)]
    if found.status == "failed" and fail_msg:
        return found.status, fail_msg
    message = found.message.format(**facts)
    if found.status == "singular" and hint:
        message += f" — {hint}"
    return found.status, message
