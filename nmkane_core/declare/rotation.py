"""A rigid body's orientation in the paper's terms: a unit quaternion (no gimbal lock), or Euler angles.

Three angles cannot describe every orientation smoothly: ZYX (yaw–pitch–roll) angles have rates
``ψ̇ = (ω2 sin φ + ω3 cos φ)/cos θ`` and lose one degree of freedom at θ = ±π/2 (gimbal lock),
where the kinematics q̇ = C u degenerate and a run stops ``singular`` (docs/how-it-works.md §7).
A unit quaternion q = (q0, q1, q2, q3) has no such position, at the price of a fourth coordinate.
The library integrates as many speeds as coordinates (the state is [q; u]), so the quaternion
comes with a fourth speed, the rate of its norm: the nonminimal form

    q̇ = ½ q ⊗ (0, ω) + ½ s q,      ψ = q·q − 1 = 0 (holonomic),

with ω the body rates.  C = ½ [Gᵀ(q) | q] has orthogonal rows of length |q|/2, so it is invertible
wherever q ≠ 0 and its estimate is 1 at every state; ψ̇ = s |q|² makes s a dependent speed, solved
from the constraint (s = 0 on it), and the rotation matrix of q/|q| turns at the body rates ω for
any |q| and s.  s moves no mass: :meth:`Rotation.inertia` gives it a fictitious inertia (the mean
principal moment), which leaves the motion as it is — ψ̇'s row of the constraints has s alone, so
the paper's solve, the rank-robust solve (Gauss's principle in the mass metric) and the projections
all give s from the constraint and ω from the body's own inertia — and keeps Q positive definite
for the rank-robust solve and the mass-weighted projections.

* :func:`quaternion_kinematics` — plain symbols, for a model written out (``MechanicalModel``);
* :func:`quaternion_frame` — dynamicsymbols and a frame oriented by the quaternion, for
  ``MechanicalModel.from_mechanics`` (``rotations=(rotation,)`` gives s its inertia there);
* :func:`zyx_kinematics` — the same description with ZYX Euler angles (singular at θ = ±π/2);
* :func:`quaternion_from_matrix`, :func:`quaternion_from_axis_angle`, :func:`quaternion_from_zyx`
  — numbers for an initial state: give all four components (q0 is completed from the others
  otherwise, which fails near a half turn, where q0 ≈ 0).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import sympy as sp

__all__ = [
    "Rotation",
    "quaternion_frame",
    "quaternion_from_axis_angle",
    "quaternion_from_matrix",
    "quaternion_from_zyx",
    "quaternion_kinematics",
    "zyx_kinematics",
]


@dataclass(frozen=True)
class Rotation:
    """A body's orientation: coordinates, body rates, kinematics, constraints and rotation matrix.

    Attributes
    ----------
    coordinates : tuple of sympy.Symbol
        (q0, q1, q2, q3) of a quaternion (scalar first), or (ψ, θ, φ) of ZYX angles.
    rates : tuple of sympy.Symbol
        The body rates (ω1, ω2, ω3): the angular velocity's components along the body's axes.
    norm_rate : sympy.Symbol or None
        The quaternion's fourth speed s (None for Euler angles).
    C, D : sympy.Matrix
        The block of (1) q̇ = C u + D for these coordinates and :attr:`speeds`.
    R : sympy.Matrix
        The rotation from the body's axes to the reference frame's (its columns are the body's
        axes): for a quaternion, of q/|q| — orthogonal at any |q|.
    holonomic : dict of str to sympy.Expr
        The constraints the coordinates bring: ``{"unit": q·q − 1}`` for a quaternion.
    """

    coordinates: tuple
    rates: tuple
    norm_rate: sp.Symbol | None
    C: sp.Matrix
    D: sp.Matrix
    R: sp.Matrix
    holonomic: dict = field(default_factory=dict)

    @property
    def speeds(self) -> tuple:
        """The speeds of :attr:`C`'s columns: the body rates, then the norm rate s (a quaternion)."""
        return self.rates + ((self.norm_rate,) if self.norm_rate is not None else ())

    @property
    def kd_eqs(self) -> list:
        """The kinematical differential equations q̇ − C u − D (for ``from_mechanics``; dynamicsymbols)."""
        from sympy.physics.mechanics import dynamicsymbols

        t = dynamicsymbols._t
        qdot = self.C * sp.Matrix(self.speeds) + self.D
        return [q.diff(t) - e for q, e in zip(self.coordinates, qdot, strict=True)]

    def inertia(self, I: sp.Matrix) -> sp.Matrix:
        """The block of the holonomic system's Q for :attr:`speeds`: the body's inertia I about its
        fixed point or centre of mass (3×3, body axes), and for a quaternion the norm rate's
        fictitious inertia :meth:`norm_inertia` on the diagonal."""
        I = sp.Matrix(I)
        if self.norm_rate is None:
            return I
        return sp.diag(I, self.norm_inertia(I))

    @staticmethod
    def norm_inertia(I: sp.Matrix) -> sp.Expr:
        """The inertia s is given: the mean of I's diagonal (the mean principal moment), of I's
        scale so that Q stays well conditioned.  Any positive value gives the same motion."""
        I = sp.Matrix(I)
        return (I[0, 0] + I[1, 1] + I[2, 2]) / 3

    def gyroscopic(self, I: sp.Matrix) -> sp.Matrix:
        """The block of P for :attr:`speeds`: Euler's −ω × Iω (and 0 for s)."""
        w = sp.Matrix(self.rates)
        P = -w.cross(sp.Matrix(I) * w)
        return P.col_join(sp.zeros(1, 1)) if self.norm_rate is not None else P

    def kinetic_energy(self, I: sp.Matrix) -> sp.Expr:
        """½ ωᵀ I ω."""
        w = sp.Matrix(self.rates)
        return (w.T * sp.Matrix(I) * w)[0] / 2


def _quaternion(q, w, s) -> Rotation:
    q0, q1, q2, q3 = q
    Gt = sp.Matrix([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]])  # q ⊗ (0, ω) = Gᵀ ω
    C = sp.Matrix.hstack(Gt, sp.Matrix(q)) / 2
    n2 = q0**2 + q1**2 + q2**2 + q3**2
    R = sp.Matrix(
        [
            [q0**2 + q1**2 - q2**2 - q3**2, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0**2 - q1**2 + q2**2 - q3**2, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0**2 - q1**2 - q2**2 + q3**2],
        ]
    )
    return Rotation(tuple(q), tuple(w), s, C, sp.zeros(4, 1), R / n2, {"unit": n2 - 1})


def quaternion_kinematics(coordinates: str = "q0:4", rates: str = "w1:4", norm_rate: str = "s") -> Rotation:
    """A unit quaternion's description in plain symbols (for a model written out).

    Parameters
    ----------
    coordinates, rates, norm_rate : str
        Names as ``sympy.symbols`` takes them: four coordinates (scalar part first), three body
        rates and the norm rate.

    Returns
    -------
    Rotation
        ``C`` (4×4) and ``D`` for the speeds (ω1, ω2, ω3, s), ``holonomic = {"unit": q·q − 1}``,
        ``R`` of q/|q|.  In a model: the coordinates and speeds among ``q`` and ``u``, the blocks
        placed in C, D, Q (:meth:`Rotation.inertia`) and P (:meth:`Rotation.gyroscopic`), the
        constraint among the holonomic ones, s a dependent speed (out of ``u_independent``).
    """
    from ..symbolic.model import plain_symbols

    return _quaternion(plain_symbols(coordinates), plain_symbols(rates), plain_symbols(norm_rate)[0])


def quaternion_frame(parent, name: str, coordinates: str = "q0:4", rates: str = "w1:4", norm_rate: str = "s") -> tuple:
    """A reference frame oriented by a quaternion, for ``MechanicalModel.from_mechanics``.

    Parameters
    ----------
    parent : sympy.physics.vector.ReferenceFrame
        The frame it turns in.
    name : str
        The new frame's name.
    coordinates, rates, norm_rate : str
        As for :func:`quaternion_kinematics` (made dynamicsymbols here).

    Returns
    -------
    (ReferenceFrame, Rotation)
        The frame, its direction cosines those of q/|q| and its angular velocity ω1 x + ω2 y + ω3 z
        in its own axes; the rotation in dynamicsymbols (``kd_eqs``, ``holonomic``, ``speeds``).
        Pass the rotation as ``rotations=(rotation,)`` to ``from_mechanics``: the norm rate, which
        moves no mass, gets its fictitious inertia there.
    """
    from sympy.physics.mechanics import ReferenceFrame, dynamicsymbols

    rot = _quaternion(dynamicsymbols(coordinates), dynamicsymbols(rates), dynamicsymbols(norm_rate))
    frame = ReferenceFrame(name)
    frame.orient_explicit(parent, rot.R)
    frame.set_ang_vel(parent, rot.rates[0] * frame.x + rot.rates[1] * frame.y + rot.rates[2] * frame.z)
    return frame, rot


def zyx_kinematics(coordinates: str = "psi theta phi", rates: str = "w1:4") -> Rotation:
    """ZYX Euler angles (yaw ψ about z, pitch θ about the new y, roll φ about the body's x) with the
    body rates as speeds: q̇ = C(θ, φ) ω, with 1/cos θ in C — singular at θ = ±π/2 (gimbal lock)."""
    from ..symbolic.model import plain_symbols

    psi, th, ph = q = plain_symbols(coordinates)
    w = plain_symbols(rates)
    s, c, ct, tt = sp.sin(ph), sp.cos(ph), sp.cos(th), sp.tan(th)
    C = sp.Matrix([[0, s / ct, c / ct], [0, c, -s], [1, s * tt, c * tt]])
    R = _rot_z(psi) * _rot_y(th) * _rot_x(ph)
    return Rotation(q, w, None, C, sp.zeros(3, 1), R)


def _rot_x(a):
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def _rot_y(a):
    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def _rot_z(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


# ---------------------------------------------------------------------------- numbers for initial states


def quaternion_from_matrix(R) -> tuple[float, float, float, float]:
    """The unit quaternion (q0 ≥ 0) of a rotation matrix (body axes as its columns): Shepperd's
    method, from the largest of the four squares (accurate at every rotation)."""
    r = [[float(R[i][j]) for j in range(3)] for i in range(3)]
    tr = r[0][0] + r[1][1] + r[2][2]
    squares = (1 + tr, 1 + 2 * r[0][0] - tr, 1 + 2 * r[1][1] - tr, 1 + 2 * r[2][2] - tr)  # 4 q_i²
    k = max(range(4), key=lambda i: squares[i])
    d = 2 * math.sqrt(squares[k])  # 4 q_k
    if k == 0:
        q = (d / 4, (r[2][1] - r[1][2]) / d, (r[0][2] - r[2][0]) / d, (r[1][0] - r[0][1]) / d)
    elif k == 1:
        q = ((r[2][1] - r[1][2]) / d, d / 4, (r[0][1] + r[1][0]) / d, (r[0][2] + r[2][0]) / d)
    elif k == 2:
        q = ((r[0][2] - r[2][0]) / d, (r[0][1] + r[1][0]) / d, d / 4, (r[1][2] + r[2][1]) / d)
    else:
        q = ((r[1][0] - r[0][1]) / d, (r[0][2] + r[2][0]) / d, (r[1][2] + r[2][1]) / d, d / 4)
    sign = -1.0 if q[0] < 0 else 1.0
    norm = math.sqrt(sum(v * v for v in q))
    return tuple(sign * v / norm for v in q)  # type: ignore[return-value]


def quaternion_from_axis_angle(axis: Sequence[float], angle: float) -> tuple[float, float, float, float]:
    """The unit quaternion of a turn by ``angle`` (rad) about ``axis`` (any length but zero)."""
    n = math.sqrt(sum(float(a) ** 2 for a in axis))
    if not n > 0:
        raise ValueError("the axis of a rotation must not be zero")
    s = math.sin(angle / 2) / n
    return (math.cos(angle / 2), float(axis[0]) * s, float(axis[1]) * s, float(axis[2]) * s)


def quaternion_from_zyx(yaw: float, pitch: float, roll: float) -> tuple[float, float, float, float]:
    """The unit quaternion of ZYX Euler angles: R = R_z(yaw) R_y(pitch) R_x(roll)."""
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    cp, sp_ = math.cos(pitch / 2), math.sin(pitch / 2)
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    return (
        cy * cp * cr + sy * sp_ * sr,
        cy * cp * sr - sy * sp_ * cr,
        cy * sp_ * cr + sy * cp * sr,
        sy * cp * cr - cy * sp_ * sr,
    )
