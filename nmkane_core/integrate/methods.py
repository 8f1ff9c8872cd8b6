"""Integrators as data.

Every explicit Runge–Kutta method is a :class:`Tableau` (``A``, ``b``, ``c`` and, for
embedded pairs, the error weights ``E``); one compiled fixed-step loop and one compiled
adaptive loop (:mod:`nmkane_core.kernel.source.loops`) serve them all, as scipy's
``rk_step`` does.  scipy's ``solve_ivp`` methods come through one adapter
(:class:`ScipyMethod`).

Names (CLI ``--integrator``, REST ``integrator``):

========================  ===============================================================
``rk4``                   classical 4th-order Runge–Kutta, fixed step
``kutta-merson``          Kutta–Merson (Merson 1957), 5 stages, 4th order, fixed step (the
                          paper's integrator)
``kutta-merson-adaptive`` the same with its embedded error estimate
                          h(2k1 − 9k3 + 8k4 − k5)/30 controlling the step
``rk45``, ``dop853``,     scipy.integrate's Runge–Kutta 4(5), Dormand–Prince 8(5,3) and
``radau``                 Radau IIA (implicit) through the adapter
========================  ===============================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

__all__ = ["MethodKind", "Tableau", "ScipyMethod", "INTEGRATORS", "get_integrator", "integrator_names"]

#: what drives a method: the compiled fixed-step loop, the compiled adaptive loop, or scipy's
#: solver stepped from Python (:data:`nmkane_core.integrate.drivers.DRIVERS`); every caller that
#: treats the kinds differently looks its kind up in a table keyed by this
MethodKind = Literal["fixed", "adaptive", "scipy"]


@dataclass(frozen=True)
class Tableau:
    """An explicit Runge–Kutta method: c | A over b (and E = b − b̂ for an error estimate)."""

    name: str
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    order: int
    E: np.ndarray | None = None  # error weights: err = h Σ E_i k_i
    error_order: int | None = None  # order of the embedded estimate (step exponent 1/(q+1))
    adaptive: bool = False
    description: str = ""

    @property
    def kind(self) -> MethodKind:
        return "adaptive" if self.adaptive else "fixed"

    @property
    def stages(self) -> int:
        return len(self.c)

    def as_adaptive(self, name: str, description: str) -> Tableau:
        if self.E is None:
            raise ValueError(f"{self.name} has no embedded error estimate")
        return Tableau(name, self.A, self.b, self.c, self.order, self.E, self.error_order, True, description)


def _arr(rows) -> np.ndarray:
    return np.array(rows, dtype=float)


RK4 = Tableau(
    "rk4",
    A=_arr([[0, 0, 0, 0], [0.5, 0, 0, 0], [0, 0.5, 0, 0], [0, 0, 1, 0]]),
    b=_arr([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
    c=_arr([0, 0.5, 0.5, 1]),
    order=4,
    description="classical Runge–Kutta, 4th order, fixed step",
)

# Kutta–Merson: Hairer, Nørsett & Wanner, Solving ODEs I, Table 4.1 (Merson 1957)
KUTTA_MERSON = Tableau(
    "kutta-merson",
    A=_arr(
        [
            [0, 0, 0, 0, 0],
            [1 / 3, 0, 0, 0, 0],
            [1 / 6, 1 / 6, 0, 0, 0],
            [1 / 8, 0, 3 / 8, 0, 0],
            [1 / 2, 0, -3 / 2, 2, 0],
        ]
    ),
    b=_arr([1 / 6, 0, 0, 2 / 3, 1 / 6]),
    c=_arr([0, 1 / 3, 1 / 3, 1 / 2, 1]),
    order=4,
    E=_arr([2 / 30, 0, -9 / 30, 8 / 30, -1 / 30]),
    error_order=3,
    description="Kutta–Merson, 5 stages, 4th order, fixed step (the paper's integrator)",
)

KUTTA_MERSON_ADAPTIVE = KUTTA_MERSON.as_adaptive(
    "kutta-merson-adaptive", "Kutta–Merson with its embedded error estimate controlling the step"
)


@dataclass(frozen=True)
class ScipyMethod:
    """A ``scipy.integrate`` OdeSolver class used step by step (partial results kept)."""

    name: str
    solver: str  # scipy class name: RK45, DOP853, Radau
    order: int
    description: str
    adaptive: bool = True

    @property
    def kind(self) -> MethodKind:
        return "scipy"


INTEGRATORS = {
    m.name: m
    for m in (
        RK4,
        KUTTA_MERSON,
        KUTTA_MERSON_ADAPTIVE,
        ScipyMethod("rk45", "RK45", 5, "scipy Runge–Kutta 4(5) (Dormand–Prince), adaptive"),
        ScipyMethod("dop853", "DOP853", 8, "scipy Dormand–Prince 8(5,3), adaptive"),
        ScipyMethod("radau", "Radau", 5, "scipy Radau IIA (implicit, for stiff gains), adaptive"),
    )
}


def integrator_names() -> tuple[str, ...]:
    return tuple(INTEGRATORS)


def get_integrator(name: str):
    from ..errors import InputError

    try:
        return INTEGRATORS[name]
    except KeyError:
        raise InputError("integrator", name, " | ".join(INTEGRATORS), "unknown integrator") from None
