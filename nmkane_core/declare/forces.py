"""Where a system's constraint forces act, declared with it: physical forces at points.

The run of a system reports the *generalized* constraint force F_c = Q u̇ − P (one number
per speed) and the multipliers λ with F_c = Jᵀλ (one per constraint).  Neither is by itself
the force at a contact point: F_c lives in the space of the speeds, and λ depends on how a
constraint is written (scale it by 2 and λ halves).  A system says where its constraints act
and in which frame the components are wanted, ``System(forces=fn)``, where ``fn(variant)``
(or ``fn()``; sympy inside: called only when the compiled form is not cached yet) returns
:class:`Forces` — one :class:`PointForce` per force: a world point (the visuals' world), the
force's components along up to three axes there (columns of a 3×k matrix, orthonormal), and
the components themselves as sympy expressions.  A component expression may use

* the coordinates, speeds and outputs of the model, the parameters and the time ``t``;
* :func:`multiplier` ``(constraint)`` — λ of a constraint of that variant (the run's);
* :func:`generalized` ``(speed)`` — F_c of a speed (the run's);
* :func:`rate` ``(name)`` — q̇ or u̇ of a coordinate or speed (the run's derivative, the
  stabilization terms included); sympy's ``Derivative`` of a ``dynamicsymbol`` coordinate or
  speed (``u1(t).diff(t)``, what ``Point.acc`` gives) means the same.

Two routes give the force at a point, and each declared force says which it takes
(``route``, shown to users):

``"multipliers"``
    For constraints written on the velocity of the point P where the force acts —
    φ_i(v_P) = 0, e.g. v_P · e_i = 0 for a contact that cannot slip along e_i — the force on
    the body at P is  R = Σ_i λ_i ∂φ_i/∂v_P  (its generalized force R · ∂v_P/∂u is then
    Σ_i λ_i ∂φ_i/∂u = Jᵀλ = F_c, Chetaev's form of the constraint force).
    :func:`constraint_force` writes that sum.  A constraint nonlinear in the speeds gives a
    gradient that depends on the velocity (|v_o|² = a²φ̇² gives 2 v_o).
``"newton"``
    A force that the chosen coordinates make non-contributing — a rolling disk's normal
    force when the height of its centre is built into the coordinates, the normal force
    under a wheel whose height the coordinates fix — never enters F_c, and no λ belongs to it.  Newton's law on
    the body (or on the whole system) gives it:  R = Σ m a_G − F_applied − (the other
    constraint forces), a_G an expression of q, u and u̇ (:func:`rate`).

``"generalized"`` names a component read straight from F_c (when a speed is the velocity of
the point along the force: F_c of that speed *is* the component).  Several routes may be mixed
in one force (``route="multipliers + newton"``).

What is declared is compiled into numpy source by :mod:`nmkane_core.kernel.forces` once per
system and variant and cached on disk (like visuals and events), so runs evaluate it without
sympy; :mod:`nmkane_core.run.forces` applies it to every run: ``Run.point_forces``.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import InputError

__all__ = [
    "Forces",
    "PointForce",
    "ROUTES",
    "constraint_force",
    "generalized",
    "multiplier",
    "rate",
]

#: how a declared force is obtained (see the module's docstring)
ROUTES = ("multipliers", "newton", "generalized")

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

# reserved symbol names: a prefix no model, parameter or state name can have (they are
# identifiers), so the compiled form can tell them from the state and parameters
LAMBDA_PREFIX = "λ:"
FC_PREFIX = "Fc:"
RATE_PREFIX = "rate:"


def multiplier(constraint: str):
    """The symbol of λ of ``constraint`` (a name of the variant's constraints), for component expressions."""
    import sympy as sp

    return sp.Symbol(LAMBDA_PREFIX + str(constraint), real=True)


def generalized(speed: str):
    """The symbol of F_c of ``speed`` (the generalized constraint force of that speed)."""
    import sympy as sp

    return sp.Symbol(FC_PREFIX + str(speed), real=True)


def rate(name: str):
    """The symbol of the time derivative of a coordinate (q̇) or speed (u̇) named ``name``:
    the run's own derivative at each output row (its stabilization terms included)."""
    import sympy as sp

    return sp.Symbol(RATE_PREFIX + str(name), real=True)


def constraint_force(gradients: dict, components: int = 3) -> tuple:
    """Components R = Σ_i λ_i ∂φ_i/∂v_P of the force of constraints written on a point's velocity.

    ``gradients``: ``{constraint name: ∂φ_i/∂v_P}``, each a sequence of ``components``
    expressions — the gradient's components along the force's axes (the
    :class:`PointForce`'s ``frame``); e.g. a blade whose constraint is v_P · B.y = 0 has the
    gradient (0, 1) in (B.x, B.y).  Returns the ``components`` expressions of R.
    """
    import sympy as sp

    out = [sp.S.Zero] * components
    for name, grad in gradients.items():
        g = tuple(grad)
        if len(g) != components:
            raise InputError(
                f"forces: gradient of {name}", g, f"{components} expressions (one per axis)", "wrong length"
            )
        lam = multiplier(name)
        out = [o + lam * sp.sympify(gi) for o, gi in zip(out, g, strict=True)]
    return tuple(out)


@dataclass(frozen=True)
class PointForce:
    """One physical force at a point: what acts there, along which axes, from which route.

    Parameters
    ----------
    name : str
        An identifier (``contact``, ``blade``, ``rear_tyre``): its components are reported
        as ``NAME.LABEL`` (``contact.normal``).
    at : sequence of 3 expressions
        The world point where it acts (the visuals' world: what the web page draws), of the
        coordinates, speeds and parameters.
    components : sequence of 1 to 3 expressions
        The force on the body (``on``) along the ``frame``'s axes.
    frame : 3×k matrix or None
        The axes of the components as columns, world coordinates, orthonormal (a rotation's
        first k columns), of the coordinates and parameters; None: the world's x, y, z.
    labels : sequence of str
        One name per component (default ``x``, ``y``, ``z``).
    route : str
        How it is obtained: ``multipliers``, ``newton``, ``generalized`` or several joined by
        ``+`` (documentation for users; see the module's docstring).
    on : str
        What it acts on (``"the disk, at its contact point"``).
    description : str
        One sentence for users.
    """

    name: str
    at: Sequence[Any]
    components: Sequence[Any]
    frame: Any = None
    labels: Sequence[str] = ("x", "y", "z")
    route: str = "multipliers"
    on: str = ""
    description: str = ""

    def __post_init__(self):
        where = f"forces.{self.name}"
        if not isinstance(self.name, str) or not _NAME.match(self.name):
            raise InputError("forces.name", self.name, "an identifier such as 'contact'", "bad name")
        object.__setattr__(self, "at", tuple(self.at))
        object.__setattr__(self, "components", tuple(self.components))
        k = len(self.components)
        if len(self.at) != 3:
            raise InputError(f"{where}.at", len(self.at), "a world point of 3 expressions", "bad point")
        if not 1 <= k <= 3:
            raise InputError(f"{where}.components", k, "1 to 3 expressions", "bad number of components")
        labels = tuple(self.labels)[:k] if tuple(self.labels) == ("x", "y", "z") else tuple(self.labels)
        object.__setattr__(self, "labels", labels)
        if len(labels) != k or len(set(labels)) != k or not all(isinstance(s, str) and _NAME.match(s) for s in labels):
            raise InputError(f"{where}.labels", labels, f"{k} different identifiers, one per component", "bad labels")
        routes = [r.strip() for r in str(self.route).split("+")]
        if not routes or any(r not in ROUTES for r in routes):
            raise InputError(f"{where}.route", self.route, " | ".join(ROUTES) + " (or several joined by +)", "unknown")
        object.__setattr__(self, "route", " + ".join(routes))

    @property
    def columns(self) -> tuple[str, ...]:
        """The reported names of the components: ``NAME.LABEL``."""
        return tuple(f"{self.name}.{label}" for label in self.labels)


@dataclass(frozen=True)
class Forces:
    """A system's (one variant's) declared physical forces.

    ``forces``: :class:`PointForce` s; ``scale``: a suggested arrow length per newton for
    drawings, m/N (None: the viewer picks one from the largest force); ``show``: whether a
    viewer draws them when the system opens (where they teach something)."""

    forces: tuple = ()
    scale: float | None = None
    show: bool = True

    def __post_init__(self):
        object.__setattr__(self, "forces", tuple(self.forces))
        for f in self.forces:
            if not isinstance(f, PointForce):
                raise InputError("forces", type(f).__name__, "PointForce(...)", "not a PointForce")
        names = [f.name for f in self.forces]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise InputError("forces", dup, "each force name once", "declared twice")
        if self.scale is not None and not (isinstance(self.scale, (int, float)) and self.scale > 0):
            raise InputError("forces.scale", self.scale, "a positive number (m per N) or None", "bad scale")
