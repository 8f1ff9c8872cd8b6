"""A rigid body on a blade (knife edge) in the horizontal plane, from sympy.physics.mechanics:
the shared model of the knife edge and the Chaplygin sleigh.

The blade's contact point P is at (x, y), its heading θ; speeds in the body frame:
u1 = forward speed of P, u2 = its sideways speed, u3 = θ̇.  The mass centre G is a
distance ``a`` ahead of P along the blade (a = 0: the knife edge).  The blade cannot slip
sideways: u2 = 0 (linear nonholonomic constraint); u_I = (u1, u3).
"""

from __future__ import annotations


def blade_model(name: str, with_offset: bool):
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    x, y, th = me.dynamicsymbols("x y theta")
    u1, u2, u3 = me.dynamicsymbols("u1 u2 u3")
    m, I = sp.symbols("m I", positive=True)
    a = sp.symbols("a", real=True) if with_offset else sp.S.Zero
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", (th, N.z))
    B.set_ang_vel(N, u3 * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, u1 * B.x + u2 * B.y)
    G = P.locatenew("G", a * B.x)
    G.v2pt_theory(P, N, B)
    body = me.RigidBody("body", G, B, m, (me.inertia(B, 0, 0, I), G))
    kd = [
        x.diff() - (u1 * sp.cos(th) - u2 * sp.sin(th)),
        y.diff() - (u1 * sp.sin(th) + u2 * sp.cos(th)),
        th.diff() - u3,
    ]
    params = (m, I, a) if with_offset else (m, I)
    energy = m / 2 * (u1**2 + (u2 + a * u3) ** 2) + I / 2 * u3**2
    return MechanicalModel.from_mechanics(
        name,
        q=[x, y, th],
        u=[u1, u2, u3],
        kd_eqs=kd,
        bodies=[body],
        loads=[],
        frame=N,
        params=params,
        nonholonomic={"no_side_slip": u2},
        u_independent=(u1, u3),
        energy=energy,
        description="a blade that cannot slip sideways (u2 = 0)",
    )


def blade_force(on: str):
    """The blade's constraint force at its contact point P = (x, y, 0), along B.y (sideways).

    The constraint u2 = v_P · B.y = 0 is written on P's velocity: the force on the body at P
    is R = λ ∂u2/∂v_P = λ B.y, its one component along B.y is λ (the multiplier route).  The
    model is planar: the ground's normal force (weight) is not part of it."""
    import sympy as sp

    from ..declare.forces import Forces, PointForce, constraint_force
    from ..symbolic.model import plain_symbols

    x, y, th = plain_symbols("x y theta")
    return Forces(
        forces=(
            PointForce(
                "blade",
                at=(x, y, sp.Float(0.02)),
                components=constraint_force({"no_side_slip": (1,)}, components=1),
                frame=sp.Matrix([-sp.sin(th), sp.cos(th), 0]),
                labels=("lateral",),
                route="multipliers",
                on=on,
                description="the ground's sideways force on the blade, the only force on the body: it keeps the "
                "blade from slipping and does no work",
            ),
        ),
    )
