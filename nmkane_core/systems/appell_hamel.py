"""Example 1 of the paper: the Appell–Hamel mechanism (Fig. 1), eqs. (51)–(103).

A frame slides on the x–y plane carrying two massless pulleys ρ apart; a thread wound on
a drum (radius b) of a wheel W (radius a, mass M, equal central moments of inertia I)
runs over the pulleys to a load P (mass m) that moves along the frame's vertical bar.
Coordinates q = (θ, φ, x, y, z), speeds u1..u5 = (θ̇, φ̇, ẋ, ẏ, ż), u_I = (u1, u2).

The holonomic equations Q u̇ = P come from sympy.physics.mechanics' KanesMethod on the
*unconstrained* system (the wheel as a rigid body, the load as a particle, gravity); the
tests check them against the paper's (99)–(100).  Two constraint models of the same
mechanism: ``nonlinear`` (57)+(58)+(59) and ``linear`` (101)+(102)+(59).

Visuals (`_visuals`): the frame, wheel, pulleys, thread and load as the viewer draws
them.  Everything riding on the frame is placed in the *body frame*: origin at P's (x, y)
on the plane, x along the heading θ, y along the wheel's axle, z up.  The wheel centre o is
ρ behind P at height a (53)–(54) and spins by φ about the axle; the drum (radius b) sits
beside the disk, the thread leaves its rear vertically, runs over two pulleys of radius b
and hangs P: z = z0 − bφ (59).  The paper gives no pulley height: the axles are 2 m above
the highest start point of the load or the wheel, h = max(z0, 2a + b) + 2.  The paper's
load keeps falling below the plane (z < 0): its bar continues through a hole in the plane.
"""

from __future__ import annotations

from ..declare.system import Parameter, System

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

WHAT_TO_TRY = (
    "The load falls and pulls the thread: the wheel spins up (u2 = φ̇ grows) while the frame's turning "
    "rate u1 = θ̇ dies away, and the load's path on the plane (the red trace, Fig. 7) straightens out. "
    "Compare with (ghost) → linear: the same mechanism with the rolling constraints linear in the speeds "
    "(101)–(102); on the constraint manifold both describe the same motion, and with the same step the "
    "energy error ΔE of the nonlinear model grows less (Fig. 9). Set Γ below 0: the rolling constraints' "
    "violations at the end of a run drop by orders of magnitude, but at Δt = 0.01 the largest, early in "
    "the run, grows with |Γ| (3× at Γ = −10, over 100× at −50); a smaller step brings it down. "
    "Set u2 = φ̇ to 0: the nonlinear model's J2 is singular where the wheel does not "
    "roll, and the run switches to the linear model (the status line says when). "
    "Both models give the same forces: the thread tension (thread.tension, m (g + z̈): below m g = 9.81 N "
    "while the load speeds up) and the ground's force on the wheel (contact.longitudinal along the rolling "
    "direction, contact.lateral across it: the sideways force that keeps the wheel from slipping and turns "
    "the frame); their multipliers differ (the nonlinear model's rolling_speed multiplier is a force "
    "divided by 2 a φ̇)."
)

INITIAL_CONTROLS = {  # the sliders of the independent initial values (ranges around the paper's)
    "theta": (-2.0, 2.0, "θ (frame's heading) [rad]"),
    "phi": (-2.0, 2.0, "φ (wheel's angle) [rad]"),
    "x": (-2.0, 2.0, "x [m] (load P on the plane)"),
    "y": (-2.0, 2.0, "y [m] (load P on the plane)"),
    "u1": (-2.0, 4.0, "u1 = θ̇ (frame's turning rate) [rad/s]"),
    "u2": (-2.0, 4.0, "u2 = φ̇ (wheel's spin) [rad/s]"),
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

    from ..symbolic.model import MechanicalModel, plain_symbols

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


MEMBER = 0.18  # m, thickness of the frame's members
LOAD_RADIUS = 0.35  # m, the load P drawn as a ball (the paper's P is a particle)
BAR_Y = -0.22  # m, P's guide bar runs just behind the thread (body y)
FRAME_COLOR = (150, 160, 178)


def _visuals():
    import sympy as sp

    from ..declare.visuals import (
        Frame,
        Visuals,
        box,
        cylinder,
        ground,
        label,
        polyline,
        rod,
        rot_y,
        rot_z,
        segments,
        sphere,
        trace,
    )
    from ..symbolic.model import plain_symbols

    th, ph, x, y, z = plain_symbols(COORDINATES)
    a, b, rho, z0 = sp.symbols("a b rho z0", real=True)
    h = sp.Max(z0, 2 * a + b) + 2  # pulley axles
    w, dl = 0.15 * a, 0.3 * a  # wheel width, drum length
    drum_y = w / 2 + 0.05 * a + dl / 2
    yl, yr = -(w / 2 + 0.15), drum_y + dl / 2 + 0.15  # the fork's struts either side of disk and drum
    spread = sp.Max(3, 0.15 * h)  # the legs' feet on the plane
    Rz = rot_z(th)

    def world(px, py, pz):  # a body-frame point in the world
        return tuple(sp.Matrix([x, y, 0]) + Rz * sp.Matrix([px, py, pz]))

    members = {
        "beam": ((-rho - 0.4, yl, h), (0.4, yl, h)),  # carries the pulleys
        "fork_left": ((-rho, yl, a), (-rho, yl, h)),  # holds the axle
        "fork_right": ((-rho, yr, a), (-rho, yr, h)),
        "fork_top": ((-rho, yl, h), (-rho, yr, h)),  # pulley 1's axle
        "pulley2_axle": ((-b, yl, h), (-b, 0.15, h)),
        "bar": ((0, BAR_Y, 0), (0, BAR_Y, h)),  # P's guide
        "bar_arm": ((0, BAR_Y, h), (0.4, yl, h)),
        "leg_left": ((-0.6, yl, h), (-0.6, yl - spread, 0)),  # the two legs that slide on the plane
        "leg_right": ((-0.6, yl, h), (-0.6, yl + spread, 0)),
    }
    frame = [rod(k, "body", p, q, MEMBER, FRAME_COLOR) for k, (p, q) in members.items()]
    frame += [
        rod("axle", "body", (-rho, yl, a), (-rho, yr, a), 0.06, FRAME_COLOR),
        box("foot_left", "body", (1.2, 0.3, 0.08), (-0.6, yl - spread, 0.04), FRAME_COLOR),
        box("foot_right", "body", (1.2, 0.3, 0.08), (-0.6, yl + spread, 0.04), FRAME_COLOR),
        cylinder("pulley1", "body", b, 0.12, "y", (-rho, drum_y, h), (200, 140, 40)),
        cylinder("pulley2", "body", b, 0.12, "y", (-b, 0, h), (200, 140, 40)),
        cylinder("hole", "body", 0.5, 0.02, "z", (0, BAR_Y / 2, 0.012), (45, 40, 35), opacity=0.75),
    ]
    wheel = [
        cylinder("disk", "wheel", a, w, "y", color=(48, 88, 196)),
        box("stripe", "wheel", (0.92 * a, w + 0.02, 0.12 * a), (0.46 * a, 0, 0), (245, 245, 245)),
        cylinder("drum", "wheel", b, dl, "y", (0, drum_y, 0), (226, 178, 40)),
        box("drum_stripe", "wheel", (0.9 * b, dl + 0.02, 0.1 * b), (0.45 * b, drum_y, 0), (120, 80, 10)),
    ]
    # the thread: off the drum's rear, over pulley 1, over pulley 2, down to the load
    arc = [sp.pi - sp.pi / 2 * k / 7 for k in range(8)]
    thread = [(-rho - b, drum_y, a)] + [(-rho + b * sp.cos(t), drum_y, h + b * sp.sin(t)) for t in arc]
    thread += [(-b + b * sp.cos(t - sp.pi / 2), 0, h + b * sp.sin(t - sp.pi / 2)) for t in arc]
    return Visuals(
        frames=(
            Frame("body", (x, y, 0), Rz),
            Frame("wheel", world(-rho, 0, a), Rz * rot_y(ph)),
        ),
        shapes=(
            ground(0),
            *frame,
            *wheel,
            sphere("load", LOAD_RADIUS, at=(x, y, z), color=(36, 160, 72)),
            polyline("thread", [world(*p) for p in thread] + [(x, y, z + LOAD_RADIUS)], (120, 30, 20), 2.0),
            # below the plane the bar goes on through the hole, as deep as the load goes
            segments("pit", [((x, y, 0), (x, y, (z - sp.Abs(z)) / 2 - LOAD_RADIUS - 1))], FRAME_COLOR, 6.0),
            trace("trace", (x, y, 0.1), thickness=3.5),  # P's intercept on the plane (Fig. 7)
            label("load_label", "load P", (x, y, z + 2 * LOAD_RADIUS)),
            label("wheel_label", "wheel W", frame="body", offset=(-rho, yl - 0.3, 2 * a + 0.3)),
            label("pulley_label", "pulleys", frame="body", offset=(-rho / 2, drum_y, h + b + 0.5)),
        ),
        view=(-0.5, 0.85, 0.3),  # from behind, on the drum's side, a little above
    )


def _forces(variant: str):
    """The ground's horizontal force on the wheel at its contact point and the thread's pull on
    the load, both by the multiplier route.

    The wheel's material contact point C (below the centre o) has velocity
    v_C = v_o − a φ̇ H.x.  ``linear``: (101), (102) are −v_C · N.x, −v_C · N.y, so the force at C
    is R = −λ_rolling_x N.x − λ_rolling_y N.y.  ``nonlinear``: (57) |v_o|² − a²φ̇² and (58)
    −v_o · H.y are written on v_o and φ̇; their Appell–Chetaev force is the force at C
    R = λ_rolling_speed ∂(57)/∂v_o + λ_no_side_slip ∂(58)/∂v_o = 2 λ_rolling_speed v_o − λ_no_side_slip H.y
    (on the constraints the φ̇ part of (57)'s gradient, −2a²φ̇, is exactly the torque of that force
    about the axle: a·(2 λ v_o · H.x) with v_o · H.x = a φ̇).  Components along the heading H.x
    and the axle H.y.  The normal force on the wheel is not reported: how the weight is shared
    between the wheel and the massless frame's supports is not part of the paper's model.

    The thread (59), ψ = z + bφ − z0, has ψ̇ = ż + b φ̇: the force λ_thread along z on the load
    (and the torque b λ_thread on the drum) — the thread tension, the same number in both
    models (it is F_c of ż, and the linear and nonlinear constraints do not involve ż)."""
    import sympy as sp

    from ..declare.forces import Forces, PointForce, constraint_force, multiplier
    from ..symbolic.model import plain_symbols

    th, x, y, z = plain_symbols("theta x y z")
    u1, u3, u4 = plain_symbols("u1 u3 u4")
    rho = sp.Symbol("rho", real=True)
    c, s = sp.cos(th), sp.sin(th)
    Hx, Hy = sp.Matrix([c, s, 0]), sp.Matrix([-s, c, 0])
    if variant == "nonlinear":
        v_o = sp.Matrix([u3 + rho * u1 * s, u4 - rho * u1 * c, 0])
        grads = {"rolling_speed": 2 * v_o, "no_side_slip": sp.Matrix([s, -c, 0])}
    else:
        grads = {"rolling_x": sp.Matrix([-1, 0, 0]), "rolling_y": sp.Matrix([0, -1, 0])}
    R = sp.Matrix(constraint_force({k: tuple(v) for k, v in grads.items()}))  # world components
    return Forces(
        forces=(
            PointForce(
                "contact",
                at=(x - rho * c, y - rho * s, 0),
                components=(sp.simplify(R.dot(Hx)), sp.simplify(R.dot(Hy))),
                frame=Hx.row_join(Hy),
                labels=("longitudinal", "lateral"),
                route="multipliers",
                on="the wheel, at its contact point",
                description="the ground's horizontal force on the wheel: along the rolling direction and across it "
                "(the normal force is not determined by the model)",
            ),
            PointForce(
                "thread",
                at=(x, y, z + LOAD_RADIUS),
                components=(multiplier("thread"),),
                frame=sp.Matrix([0, 0, 1]),
                labels=("tension",),
                route="multipliers",
                on="the load P",
                description="the thread's pull on the load (its tension): m (g + z̈)",
            ),
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
        # the paper's solve on the declared partition: the paper's claims (and its singular J2
        # where the wheel stops rolling) are about it; solve="auto" is one option away
        default_solve="paper",
        description=(
            "The paper's Example 1: a frame sliding on the plane carries a wheel W that rolls without "
            "slipping and two pulleys; a thread from the wheel's drum over the pulleys holds a load P that "
            "moves along the frame's bar. The rolling constraints are modeled nonlinear (NC, (57)–(58)) or "
            "linear (LC, (101)–(102)) in the speeds."
        ),
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
