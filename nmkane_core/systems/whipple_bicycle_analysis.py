"""The Whipple bicycle (`nmkane_core.systems.whipple_bicycle`) about upright straight running.

`upright_state` is the full consistent state at a forward speed, and
`bicycle_eigenvalues` the eigenvalues of the roll/steer motion linearized there (the
table behind Meijaard et al. (2007) Fig. 3: capsize, weave and castor modes against speed),
both through the generic [`linearize`][nmkane_core.linearize].
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

from ..analysis.at_state import linearize
from ..errors import InputError
from ..run.initial import initial_state
from ..run.registry import get_system
from .whipple_bicycle import NAME

__all__ = ["ROLL_STEER", "bicycle_eigenvalues", "upright_state"]

#: the linearized state: roll, steer, roll rate, steer rate
ROLL_STEER = ("q4", "q7", "u4", "u7")


def upright_state(speed: float, params: Mapping[str, float] | None = None) -> dict[str, float]:
    """The full consistent state of upright straight running at ``speed`` (m/s, forward): every
    angle 0 except the pitch q5 (completed from the front contact constraint), u6 = −speed/rR,
    the dependent speeds completed; ``params`` overrides the benchmark values."""
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not math.isfinite(speed):
        raise InputError("speed", speed, "a finite forward speed in m/s", "not a finite number")
    system = get_system(NAME)
    values = system.resolve_params(params or {})
    given = dict.fromkeys(("q1", "q2", "q3", "q4", "q6", "q7", "q8", "u4", "u7"), 0.0)
    given["u6"] = -float(speed) / values["rR"]
    _, full = initial_state(system, system.default_variant, values, given)
    return full


def bicycle_eigenvalues(speeds: Iterable[float], params: Mapping[str, float] | None = None) -> list[dict]:
    """Eigenvalues of the roll/steer motion linearized about upright straight running.

    ``speeds``: forward speeds in m/s; ``params``: overrides of the benchmark values.  One
    row per speed: ``{"speed": v, "eigenvalues": [[re, im], ...]}``, four values sorted by
    real part, then imaginary part."""
    rows = []
    for v in speeds:
        lin = linearize(NAME, upright_state(v, params), params, keep=ROLL_STEER)
        ev = sorted(lin.eigenvalues, key=lambda z: (round(z.real, 9), z.imag))
        rows.append({"speed": float(v), "eigenvalues": [[float(z.real), float(z.imag)] for z in ev]})
    return rows
