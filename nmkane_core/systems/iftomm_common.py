"""Helpers shared by the IFToMM benchmark systems (``iftomm_a0N``).

:func:`rigid_bodies_QP`: the holonomic system Q u̇ = P (42) of rigid bodies whose speeds are
the coordinates' rates (q̇ = u), built entry by entry from each body's sparse Jacobians —
the same Q and P as sympy.physics.mechanics' KanesMethod (``mass_matrix``, ``forcing``;
:func:`tests.systems.test_iftomm` checks it on the small models), but linear in the number of
bodies: KanesMethod on the 81 rods of the A02 benchmark's N = 40 takes minutes (it solves
the kinematical equations and forms F* densely, about N² work).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

__all__ = ["Body", "rigid_bodies_QP"]


@dataclass
class Body:
    """A rigid body of a model with q̇ = u.

    ``r``: its mass centre (3 sympy expressions of q, world axes); ``R``: its rotation
    matrix (3×3, body axes as columns), or None for a particle; ``mass``; ``inertia``: its
    central inertia matrix in body axes (3×3); ``force``: the resultant applied force at the
    mass centre (3 expressions, world axes; e.g. gravity), ``moment``: applied moment (body
    axes).  A planar body may give ``omega`` instead of ``R``: its angular velocity, linear in
    u (world axes, e.g. (0, 0, u_k)), with ``inertia`` then constant in world axes (I_zz)."""

    r: Sequence
    mass: object
    R: object = None
    inertia: object = None
    force: Sequence = (0, 0, 0)
    moment: Sequence = (0, 0, 0)
    omega: Sequence | None = None
    name: str = field(default="")


def _jacobian_cols(e, q, index):
    """(∂e/∂q restricted to the coordinates e involves, their indices): a body's expressions
    involve a few of the model's coordinates, and differentiating by all of them was the N²
    part of building a long chain."""
    cols = sorted(index[s] for s in e.free_symbols if s in index)
    return e.jacobian([q[j] for j in cols]), cols


def rigid_bodies_QP(bodies: Sequence[Body], q: Sequence, u: Sequence):
    """(Q, P, T): Kane's generalized inertia matrix, the forcing vector and the kinetic energy.

    With q̇ = u, the partial velocities are v_G,j = ∂r_G/∂q_j and the partial angular
    velocities ω_j the columns of W with ω = W u (from Ṙ Rᵀ = [ω]×).  Kane's equations
    Σ_bodies (v_G,jᵀ (F − m a_G) + ω_jᵀ (M − I ω̇ − ω × I ω)) = 0 give
    Q = Σ m J_Gᵀ J_G + Wᵀ I_w W and P = Σ J_Gᵀ (F − m J̇_G u) + Wᵀ (M − I_w Ẇ u − ω × I_w ω),
    with I_w = R I Rᵀ (computed in body axes, where I is constant).  Entries are accumulated
    over each body's few nonzero columns."""
    import sympy as sp

    q, u = list(q), list(u)
    n = len(q)
    qd = dict(zip(q, u, strict=True))

    def dt(e):  # time derivative of an expression of q (q̇ = u)
        return sum((sp.diff(e, qi) * qd[qi] for qi in e.free_symbols & set(q)), sp.S.Zero)

    qindex = {qi: j for j, qi in enumerate(q)}
    uindex = {ui: j for j, ui in enumerate(u)}
    Q = sp.zeros(n, n)
    P = sp.zeros(n, 1)
    T = sp.S.Zero
    for b in bodies:
        r = sp.Matrix(b.r)
        JG, cols = _jacobian_cols(r, q, qindex)  # the columns of ∂r_G/∂q that can be nonzero
        v = JG * sp.Matrix([u[j] for j in cols])
        acc_vel = sp.Matrix([dt(vi) for vi in v]) if cols else sp.zeros(3, 1)  # J̇_G u (u̇ terms excluded)
        F = sp.Matrix(b.force)
        for a, i in enumerate(cols):
            for c, j in enumerate(cols):
                Q[i, j] += b.mass * JG[:, a].dot(JG[:, c])
            P[i] += JG[:, a].dot(F - b.mass * acc_vel)
        T += b.mass * v.dot(v) / 2
        if b.omega is not None:  # planar: ω = W u in world axes, inertia constant there
            w = sp.Matrix(b.omega)
            Ib = sp.Matrix(b.inertia)
            Mb = sp.Matrix(b.moment)
        elif b.R is not None:  # body axes: ω_b = vee(Rᵀ Ṙ), inertia constant there
            from ..symbolic.terms import pythagorean

            R = sp.Matrix(b.R)
            Om = (R.T * R.applyfunc(dt)).applyfunc(lambda e: pythagorean(sp.expand(e)))
            w = sp.Matrix([Om[2, 1], Om[0, 2], Om[1, 0]])
            Ib = sp.Matrix(b.inertia)
            Mb = sp.Matrix(b.moment)
        else:
            continue
        W, wcols = _jacobian_cols(w, u, uindex)
        wdot_vel = sp.Matrix([dt(wi) for wi in w]) if wcols else sp.zeros(3, 1)  # Ẇ u
        gyro = Ib * wdot_vel + w.cross(Ib * w) - Mb
        for a, i in enumerate(wcols):
            for c, j in enumerate(wcols):
                Q[i, j] += W[:, a].dot(Ib * W[:, c])
            P[i] -= W[:, a].dot(gyro)
        T += w.dot(Ib * w) / 2
    return Q.applyfunc(sp.expand), P.applyfunc(sp.expand), sp.expand(T)
