"""Example 1 of the paper: the Appell–Hamel mechanism (Fig. 1), eqs. (51)–(103).

A frame slides on the x–y plane carrying two massless pulleys ρ apart; a thread wound on
a drum (radius b) of a wheel W (radius a, mass M, equal central moments of inertia I)
runs over the pulleys to a load P (mass m) that moves along the frame's vertical bar.
Coordinates q = (θ, φ, x, y, z), speeds u1..u5 = (θ̇, φ̇, ẋ, ẏ, ż), u_I = (u1, u2).

The holonomic equations Q u̇ = P come from sympy.physics.mechanics' KanesMethod on the
*unconstrained* system (the wheel as a rigid body, the load as a particle, gravity); the
tests check them against the paper's (99)–(100).  Two constraint models of the same
mechanism: ``nonlinear`` (57)+(58)+(59) and ``linear`` (101)+(102)+(59).
"""

from __future__ import annotations

from ..system import Parameter, System

PARAMETERS = {
    "a": Parameter(1.0, 0.0, 1e3, "m", "wheel radius"),
    "b": Parameter(0.5, 0.0, 1e3, "m", "drum radius"),
    "rho": Parameter(5.0, 0.0, 1e3, "m", "distance between the pulleys (wheel centre to bar)"),
    "m": Parameter(1.0, 0.0, 1e6, "kg", "mass of the load P"),
    "M": Parameter(5.0, 0.0, 1e6, "kg", "mass of the wheel"),
    "I": Parameter(2.5, 0.0, 1e6, "kg·m²", "central moment of inertia of the wheel (all axes)"),
    "g": Parameter(9.81, 0.0, 1e3, "m/s²", "gravitational acceleration", min_inclusive=True),
    "z0": Parameter(30.0, -1e6, 1e6, "m", "height of P when φ = 0 (thread constraint (59))"),
}

COORDINATES = ("theta", "phi", "x", "y", "z")
SPEEDS = ("u1", "u2", "u3", "u4", "u5")


def _holonomic_equations():
    """Q, P of the unconstrained mechanism from bodies and loads (KanesMethod)."""
    import sympy as sp
    from sympy.physics import mechanics as me

    th, ph, x, y, z = me.dynamicsymbols("theta phi x y z")
    u = me.dynamicsymbols("u1:6")
    a, b, rho, m, M, I, g, z0 = sp.symbols("a b rho m M I g z0", real=True)
    N = me.ReferenceFrame("N")
    H = N.orientnew("H", "Axis", (th, N.z))  # heading frame: wheel plane at θ to x
    W = H.orientnew("W", "Axis", (ph, H.y))  # the wheel spins by φ about its axle H.y
    W.set_ang_vel(N, u[0] * N.z + u[1] * H.y)  # (82)
    O = me.Point("O")
    O.set_vel(N, 0)
    Pp = O.locatenew("P", x * N.x + y * N.y + z * N.z)
    Pp.set_vel(N, u[2] * N.x + u[3] * N.y + u[4] * N.z)  # (77)
    o = Pp.locatenew("o", -rho * H.x + a * N.z - z * N.z)  # wheel centre, height a
    o.set_vel(
        N, Pp.vel(N).dot(N.x) * N.x + Pp.vel(N).dot(N.y) * N.y + rho * u[0] * (sp.sin(th) * N.x - sp.cos(th) * N.y)
    )  # (84)
    wheel = me.RigidBody("W", o, W, M, (me.inertia(W, I, I, I), o))
    load = me.Particle("Pm", Pp, m)
    loads = [(Pp, -m * g * N.z), (o, -M * g * N.z)]
    q = [th, ph, x, y, z]
    kd = [qi.diff(me.dynamicsymbols._t) - ui for qi, ui in zip(q, u, strict=True)]
    params = (a, b, rho, m, M, I, g, z0)
    return dict(q=q, u=u, kd_eqs=kd, bodies=[wheel, load], loads=loads, frame=N, params=params)


def _model(name: str):
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..model import MechanicalModel, plain_symbols

    th, ph, x, y, z = plain_symbols(COORDINATES)
    u1, u2, u3, u4, u5 = plain_symbols(SPEEDS)
    a, b, rho, m, M, I, g, z0 = sp.symbols("a b rho m M I g z0", real=True)
    mech = _holonomic_equations()
    if name == "nonlinear":
        nonholonomic = {
            # (57) |v_o|² = a² φ̇²
            "rolling_speed": (u3 + rho * u1 * sp.sin(th)) ** 2 + (u4 - rho * u1 * sp.cos(th)) ** 2 - a**2 * u2**2,
            # (58) no side slip of the wheel
            "no_side_slip": u3 * sp.sin(th) - u4 * sp.cos(th) + rho * u1,
        }
    else:
        nonholonomic = {
            "rolling_x": a * u2 * sp.cos(th) - u3 - rho * u1 * sp.sin(th),  # (101)
            "rolling_y": a * u2 * sp.sin(th) - u4 + rho * u1 * sp.cos(th),  # (102)
        }
    energy = (
        I / 2 * (u1**2 + u2**2)  # (103)
        + M / 2 * ((u3 + rho * u1 * sp.sin(th)) ** 2 + (u4 - rho * u1 * sp.cos(th)) ** 2)
        + M / 2 * g * a
        + m / 2 * (u3**2 + u4**2 + u5**2)
        + m * g * z
    )
    tq = me.dynamicsymbols("theta phi x y z")
    tu = me.dynamicsymbols("u1:6")
    to_dyn = dict(zip((th, ph, x, y, z, u1, u2, u3, u4, u5), list(tq) + list(tu), strict=True))
    return MechanicalModel.from_mechanics(
        name,
        **mech,
        nonholonomic={k: v.subs(to_dyn) for k, v in nonholonomic.items()},
        holonomic={"thread": (z + b * ph - z0).subs(to_dyn)},  # (59)
        u_independent=(tu[0], tu[1]),  # (63)
        energy=energy.subs(to_dyn),
        q_dependent=(tq[4],),
        description=(
            "nonlinear nonholonomic constraints (57)–(59)"
            if name == "nonlinear"
            else "linear nonholonomic constraints (101), (102), (59)"
        ),
    )


def appell_hamel() -> System:
    return System(
        name="appell-hamel",
        title="Appell–Hamel mechanism (Example 1)",
        option="model",
        variants={"nonlinear": lambda: _model("nonlinear"), "linear": lambda: _model("linear")},
        default_variant="nonlinear",
        parameters=PARAMETERS,
        default_initial={
            "theta": 0.0,
            "phi": 0.0,
            "x": 0.0,
            "y": 0.0,
            "z": 30.0,
            "u1": 1.0,
            "u2": 1.0,
            "u3": 1.0,
            "u4": 5.0,
            "u5": -0.5,
        },
        completion_variant="linear",
        # near φ̇ = 0 the nonlinear model's J2 is singular; the linear model is equivalent there
        equivalents={"nonlinear": ("linear",)},
        singular_hints={"nonlinear": "the nonlinear model's J2 is singular where the wheel stops rolling (φ̇ = 0)"},
        default_dt=0.01,
        default_t_final=20.0,
        default_integrator="kutta-merson",
        description="Frame, wheel and hanging load; constraints modeled nonlinear (NC) or linear (LC) in the speeds.",
    )
