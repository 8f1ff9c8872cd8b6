"""Eigenvalues of a system's linearized motion against a swept value (a forward speed).

A system declares what to sweep, ``System(stability=Stability(...))``: the swept value's
name, unit and default range, a function giving the independent initial values at a
value (the rest is completed from the constraints), the independent coordinates and speeds
to linearize (:func:`nmkane_core.analysis.at_state.linearize`), and optionally names for the
crossings found (where a real eigenvalue, or the real part of a complex pair, changes
sign) and published reference values of them.  :func:`nmkane_core.analysis.eigensweep.sweep` computes the table and
:func:`~nmkane_core.analysis.eigensweep.crossings` the values where the stability changes, refined by bisection.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

__all__ = ["Stability"]


@dataclass(frozen=True)
class Stability:
    """What to sweep for a system's eigenvalue plot.

    ``over``: the swept value's name (``"speed"``); ``unit``; ``start, stop, count``: the
    default sweep; ``state(value, params)`` → independent initial values at ``value``
    (``params``: parameter name → value); ``keep``: the independent coordinates and speeds
    linearized; ``value_of(initial, params)`` → the swept value of a run's initial values
    (to mark the current one), or None; ``names``: {"complex": name, "real": name} for the
    crossings of a complex pair and of a real eigenvalue (``"fast"``: the name of the most
    negative real eigenvalue's mode, for labels); ``reference``: published crossing values
    by name."""

    over: str
    unit: str
    start: float
    stop: float
    count: int
    state: Callable[[float, Mapping[str, float]], Mapping[str, float]]
    keep: tuple[str, ...]
    value_of: Callable[[Mapping[str, float], Mapping[str, float]], float] | None = None
    names: Mapping[str, str] = field(default_factory=dict)
    reference: Mapping[str, float] = field(default_factory=dict)
