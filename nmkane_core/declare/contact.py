"""Rolling contact of a convex body on the horizontal plane, declared from the body's surface.

Given where a rigid body is (its frame's origin and rotation), how it moves (the origin's
velocity and the body's angular velocity) and the shape of its surface in body coordinates,
:func:`rolling_contact` writes the constraints of rolling without slipping on the plane
z = z0 and the contact point, as sympy expressions ready for a
:class:`~nmkane_core.symbolic.model.MechanicalModel` (``holonomic=``, ``nonholonomic=``), the
visuals (a trace of the contact point) and the forces (the point where the ground pushes).

Conventions
-----------
* World axes x, y horizontal, z up; the plane is z = z0 (default 0), the body above it.
* The body frame: origin at world position r, rotation R (3×3, the body axes as columns in
  world coordinates — ``N.dcm(B)`` for a sympy.physics.mechanics frame B in the ground N,
  as :class:`~nmkane_core.declare.visuals.Frame` takes it).  Any frame in which the surface
  is fixed will do: a wheel's rim is the same circle in a frame that leans and steers with
  the wheel but does not spin, which gives shorter expressions; the angular velocity is
  always the body's own.
* The surface is convex, in body coordinates, given by its *support function*
  h(n) = max over the body's points s of s·n, written positively homogeneous of degree one
  in n = (n1, n2, n3) (h(k n) = k h(n) for k > 0: ``sqrt(a**2*n1**2 + …)``, not a
  formula valid only for unit n).  Builders: :func:`ellipsoid`, :func:`sphere`,
  :func:`disk_edge` (a thin disk rolling on its rim), :func:`torus` (a thick wheel's
  tyre), :func:`support_surface` (any support function) and :func:`implicit_surface` (an
  implicit quadric f(s) = 0: an ellipsoid in any position and orientation).

Equations
---------
The upward vertical in body coordinates is μ = Rᵀ e_z (the third row of R).  The body's
lowest point has the outward normal −μ, so — for a strictly convex smooth surface — it is
the body point

    p = ∇h(−μ)                                   (body coordinates)
    r_P = r + R p                                (world: the contact point)

and, by Euler's relation ∇h(n)·n = h(n), its height is r_z + μ·p = r_z − h(−μ).

* **height** (holonomic): ψ = r_z − h(−μ) − z0 = 0 — the lowest point on the plane;
* **no slip** (nonholonomic, two): the velocity of the body's material point at P,
  v_P = v + ω × (R p), has no horizontal part: φ_x = v_P·e_x = 0, φ_y = v_P·e_y = 0.

The vertical part v_P·e_z is the time derivative of ψ (the contact point moves on the
surface, perpendicular to its normal −μ: d(μ·p)/dt gives no term from ṗ), so it is not a
constraint of its own: declaring it beside the height constraint would make the equations
redundant.  When the coordinates already keep the body on the plane (a disk whose centre
height is written as r cos θ), the height constraint is identically zero: leave it out and
declare only the no-slip pair.

The force the plane exerts at P is then λ_x e_x + λ_y e_y (the multipliers of the no-slip
constraints: they are written on v_P, see :mod:`nmkane_core.declare.forces`) plus the normal
force: the height constraint's multiplier, ψ̇ = v_P·e_z, when the height is a constraint.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from typing import Any

from ..errors import InputError

__all__ = [
    "RollingContact",
    "Surface",
    "disk_edge",
    "ellipsoid",
    "implicit_surface",
    "rolling_contact",
    "sphere",
    "support_surface",
    "torus",
]

AXES = ("x", "y", "z")


def _n():
    """The symbols of a normal direction, body coordinates."""
    import sympy as sp

    return sp.symbols("n1 n2 n3", real=True)


@dataclass(frozen=True)
class Surface:
    """A convex body's surface in body coordinates: its support function ``support``, an
    expression in the direction symbols ``n`` (three real symbols), positively homogeneous of
    degree one; ``point`` is ∇h — the surface point whose outward normal is n — with
    |n| = 1 used to simplify it; ``label`` says what it is (messages)."""

    support: Any
    n: tuple
    point: tuple
    label: str = "surface"

    def contact(self, up) -> tuple[Any, Any]:
        """(p, h(−μ)) for the upward vertical μ in body coordinates (3 expressions): the
        body point that touches the plane and the depth of the plane below the frame's origin."""
        import sympy as sp

        down = dict(zip(self.n, (-sp.sympify(c) for c in up), strict=True))
        p = sp.Matrix([sp.sympify(c).xreplace(down) for c in self.point])
        return p, _unit(self.support, self.n).xreplace(down)


def _unit(expr, n):
    """``expr`` with |n|² = 1: the support of a unit normal is what the contact needs, and the
    norm of a unit vector written in rotations would otherwise stay as a square root."""
    import sympy as sp

    return sp.sympify(expr).xreplace({sp.Add(*(c**2 for c in n)): sp.S.One})


def support_surface(support, n=None, label: str = "surface") -> Surface:
    """A surface from its support function h(n) (a sympy expression in the symbols ``n``,
    default ``n1 n2 n3`` real, positively homogeneous of degree one: checked numerically).

    Raises
    ------
    InputError
        When h is not homogeneous of degree one (a formula valid for unit n only, such as a
        constant radius r for a sphere, gives a wrong contact point: write r·√(n·n)).
    """
    import sympy as sp

    n = tuple(n) if n is not None else _n()
    if len(n) != 3 or not all(isinstance(s, sp.Symbol) for s in n):
        raise InputError(f"contact.{label}.n", n, "three sympy symbols", "bad direction symbols")
    h = sp.sympify(support)
    _check_homogeneous(h, n, label)
    grad = [_unit(sp.diff(h, c), n) for c in n]
    return Surface(support=h, n=n, point=tuple(grad), label=label)


def _check_homogeneous(h, n, label: str) -> None:
    """h(k n) = k h(n) at random directions and k, the other symbols at random positive values."""
    if not h.free_symbols & set(n):
        raise InputError(f"contact.{label}.support", str(h), "an expression of the direction", "constant")
    rng = random.Random(7)
    others = sorted(h.free_symbols - set(n), key=str)
    for _ in range(3):
        vals = {s: rng.uniform(0.5, 2.0) for s in others}
        d = [rng.uniform(-1.0, 1.0) for _ in n]
        k = rng.uniform(1.5, 3.0)
        at = {**vals, **dict(zip(n, d, strict=True))}
        scaled = {**vals, **{c: k * v for c, v in zip(n, d, strict=True)}}
        h1, hk = complex(h.evalf(subs=at)), complex(h.evalf(subs=scaled))
        if abs(hk - k * h1) > 1e-9 * max(1.0, abs(hk)):
            raise InputError(
                f"contact.{label}.support",
                str(h),
                f"a support function positively homogeneous of degree one in {', '.join(map(str, n))} "
                "(h(k n) = k h(n): write a sphere's r as r·sqrt(n1**2 + n2**2 + n3**2))",
                "not homogeneous of degree one",
            )


def _shifted(h, n, centre):
    """The support of a surface moved by ``centre`` (body coordinates): h(n) + n·centre."""
    import sympy as sp

    c = tuple(sp.sympify(v) for v in centre)
    if len(c) != 3:
        raise InputError("contact.centre", centre, "3 expressions (body coordinates)", "bad point")
    return h + sum((ci * ni for ci, ni in zip(c, n, strict=True)), sp.S.Zero)


def ellipsoid(a, b, c, centre=(0, 0, 0)) -> Surface:
    """The ellipsoid (x/a)² + (y/b)² + (z/c)² = 1 about ``centre`` (body coordinates):
    h(n) = √(a²n1² + b²n2² + c²n3²) + n·centre; its contact point
    p = centre − (a²μ1, b²μ2, c²μ3)/√(a²μ1² + b²μ2² + c²μ3²)."""
    import sympy as sp

    n = _n()
    h = sp.sqrt(a**2 * n[0] ** 2 + b**2 * n[1] ** 2 + c**2 * n[2] ** 2)
    return support_surface(_shifted(h, n, centre), n, "ellipsoid")


def sphere(r, centre=(0, 0, 0)) -> Surface:
    """A ball of radius r about ``centre``: h(n) = r|n| + n·centre; p = centre − r μ."""
    import sympy as sp

    n = _n()
    return support_surface(_shifted(r * sp.sqrt(sum(c**2 for c in n)), n, centre), n, "sphere")


def _axis(axis: str, label: str) -> int:
    if axis not in AXES:
        raise InputError(f"contact.{label}.axis", axis, "x | y | z", "unknown axis")
    return AXES.index(axis)


def disk_edge(r, axis: str = "y", centre=(0, 0, 0)) -> Surface:
    """The rim of a thin disk: the circle of radius r about the body ``axis`` through
    ``centre``.  h(n) = r √(|n|² − n_axis²) + n·centre; the contact point is the rim point
    straight below the centre in the disk's plane (undefined when the disk lies flat)."""
    import sympy as sp

    n = _n()
    k = _axis(axis, "disk_edge")
    h = r * sp.sqrt(sum(c**2 for i, c in enumerate(n) if i != k))
    return support_surface(_shifted(h, n, centre), n, "disk_edge")


def torus(R, r, axis: str = "y", centre=(0, 0, 0)) -> Surface:
    """The outer half of a torus about the body ``axis`` (a tyre): the tube of radius r round
    the circle of radius R.  h(n) = R √(|n|² − n_axis²) + r|n| + n·centre."""
    import sympy as sp

    n = _n()
    k = _axis(axis, "torus")
    h = R * sp.sqrt(sum(c**2 for i, c in enumerate(n) if i != k)) + r * sp.sqrt(sum(c**2 for c in n))
    return support_surface(_shifted(h, n, centre), n, "torus")


def implicit_surface(f, s, label: str = "implicit") -> Surface:
    """A closed quadric surface f(s) = 0 (``s``: three symbols, body coordinates; f < 0 inside),
    an ellipsoid in any position and orientation: f = sᵀMs + bᵀs + f0 with M positive definite.
    With its centre s0 = −M⁻¹b/2 and k = s0ᵀMs0 − f0 its support is h(n) = n·s0 + √(k nᵀM⁻¹n).

    Raises
    ------
    InputError
        When f is not a polynomial of degree two in ``s`` (a surface of higher degree has no
        closed-form contact point in general: give its support function, :func:`support_surface`).
    """
    import sympy as sp

    s = tuple(s)
    f = sp.expand(sp.sympify(f))
    try:
        degree = sp.Poly(f, *s).total_degree()
    except sp.PolynomialError:
        degree = -1
    if len(s) != 3 or degree != 2:
        raise InputError(
            f"contact.{label}",
            str(f),
            "a quadric (a polynomial of degree two in the three body coordinates), or a support function "
            "(support_surface)",
            "not a quadric",
        )
    zero = dict.fromkeys(s, 0)
    M = sp.hessian(f, s) / 2
    b = sp.Matrix([sp.diff(f, si) for si in s]).xreplace(zero)
    Minv = M.inv()
    s0 = -Minv * b / 2
    k = sp.simplify((s0.T * M * s0)[0] - f.xreplace(zero))
    n = _n()
    nv = sp.Matrix(n)
    h = (nv.T * s0)[0] + sp.sqrt(sp.factor(k * (nv.T * Minv * nv)[0]))
    return support_surface(h, n, label)


@dataclass(frozen=True)
class RollingContact:
    """What :func:`rolling_contact` declares (sympy expressions of the inputs' symbols).

    Attributes
    ----------
    body_point : sympy.Matrix
        p, the contact point in body coordinates.
    point : sympy.Matrix
        r_P = r + R p, the contact point in world coordinates (the visuals' and the forces' world).
    up : sympy.Matrix
        μ = Rᵀ e_z, the upward vertical in body coordinates.
    height : dict
        ``{name: r_z − h(−μ) − z0}``: the holonomic constraint (``MechanicalModel(holonomic=…)``).
    no_slip : dict
        ``{name_x: v_P·e_x, name_y: v_P·e_y}``: the nonholonomic constraints.
    slip_velocity : sympy.Matrix
        v_P = v + ω × (R p), world components (its z component is the height's rate).
    """

    body_point: Any
    point: Any
    up: Any
    height: dict
    no_slip: dict
    slip_velocity: Any

    def force(self, name: str = "contact", *, normal=None, on: str = "", description: str = ""):
        """The plane's force on the body at the contact point, along the world's x, y, z, as a
        :class:`~nmkane_core.declare.forces.PointForce`: friction from the no-slip constraints'
        multipliers λ_x, λ_y (they are written on v_P, whose gradients are e_x, e_y), the normal
        force from the height constraint's (its rate is v_P·e_z) — or ``normal``, an expression
        (Newton's law on the body), when the coordinates keep the body on the plane and the
        height is not a constraint."""
        from .forces import PointForce, multiplier

        fx, fy = (multiplier(k) for k in self.no_slip)
        routes = "multipliers" if normal is None else "multipliers + newton"
        fz = multiplier(next(iter(self.height))) if normal is None else normal
        return PointForce(
            name,
            at=tuple(self.point),
            components=(fx, fy, fz),
            labels=("x", "y", "normal"),
            route=routes,
            on=on,
            description=description
            or "the plane's force at the contact point: friction along x and y (the no-slip constraints' λ) and the "
            "normal force",
        )


def _vector3(value, inertial, what: str):
    """3 world components from a sequence or a sympy.physics.vector Vector (in ``inertial``)."""
    import sympy as sp

    if hasattr(value, "to_matrix"):
        if inertial is None:
            raise InputError(f"contact.{what}", str(value), "3 expressions, or a Vector with inertial=N", "no frame")
        return sp.Matrix(value.to_matrix(inertial))
    m = sp.Matrix(list(value))
    if m.shape != (3, 1):
        raise InputError(f"contact.{what}", value, "3 expressions (world components) or a Vector", "bad shape")
    return m


def _rotation(orientation, inertial):
    import sympy as sp

    if hasattr(orientation, "dcm"):
        if inertial is None:
            raise InputError("contact.orientation", str(orientation), "a ReferenceFrame with inertial=N", "no frame")
        return sp.Matrix(inertial.dcm(orientation))
    R = sp.Matrix(orientation)
    if R.shape != (3, 3):
        raise InputError("contact.orientation", R.shape, "a 3×3 rotation matrix or a ReferenceFrame", "bad shape")
    return R


def rolling_contact(
    surface: Surface,
    orientation,
    origin,
    velocity,
    angular_velocity=None,
    *,
    body_angular_velocity=None,
    inertial=None,
    plane_height=0,
    names: tuple[str, str, str] = ("no_slip_x", "no_slip_y", "on_plane"),
) -> RollingContact:
    """The contact of a convex body rolling without slipping on the plane z = ``plane_height``.

    Parameters
    ----------
    surface : Surface
        The body's surface in body coordinates (:func:`ellipsoid`, :func:`sphere`,
        :func:`disk_edge`, :func:`torus`, :func:`support_surface`, :func:`implicit_surface`).
    orientation : 3×3 matrix or ReferenceFrame
        R, the body axes as columns in world coordinates; or the body's ReferenceFrame
        (with ``inertial``: R = ``inertial.dcm(orientation)``).
    origin, velocity : 3 expressions or Vector
        The world position r of the body frame's origin and its velocity v (world components;
        a Vector is read in ``inertial``).
    angular_velocity : 3 expressions or Vector, optional
        ω, world components (or a Vector).
    body_angular_velocity : 3 expressions, optional
        ω along the axes of ``orientation`` instead (shorter expressions: v_P = v + R(ω_B × p)).
        Exactly one of the two is given.
    inertial : ReferenceFrame, optional
        The ground frame, for frames and Vectors.
    plane_height : expression, optional
        z0, the plane's height.
    names : three str
        The names of the two no-slip constraints (along world x and y) and of the height constraint.

    Returns
    -------
    RollingContact
        The contact point (body and world), the height constraint, the no-slip constraints and
        the material contact point's velocity.
    """
    import sympy as sp

    if (angular_velocity is None) == (body_angular_velocity is None):
        raise InputError(
            "contact.angular_velocity",
            (angular_velocity, body_angular_velocity),
            "exactly one of angular_velocity (world) and body_angular_velocity (body axes)",
            "both or neither given",
        )
    if len(names) != 3 or len(set(names)) != 3:
        raise InputError("contact.names", names, "three different constraint names (x, y, height)", "bad names")
    R = _rotation(orientation, inertial)
    r = _vector3(origin, inertial, "origin")
    v = _vector3(velocity, inertial, "velocity")
    up = R[2, :].T
    p, depth = surface.contact(up)
    arm = R * p
    if body_angular_velocity is not None:
        w = sp.Matrix(list(body_angular_velocity))
        if w.shape != (3, 1):
            raise InputError("contact.body_angular_velocity", w.shape, "3 expressions (body axes)", "bad shape")
        turn = R * w.cross(p)
    else:
        turn = _vector3(angular_velocity, inertial, "angular_velocity").cross(arm)
    v_p = v + turn
    return RollingContact(
        body_point=p,
        point=r + arm,
        up=up,
        height={names[2]: r[2] - depth - sp.sympify(plane_height)},
        no_slip={names[0]: v_p[0], names[1]: v_p[1]},
        slip_velocity=v_p,
    )
