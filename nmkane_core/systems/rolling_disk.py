"""A uniform thin disk rolling without slipping on a horizontal plane (sympy.physics.mechanics).

Coordinates: the contact point (x, y), yaw ψ, lean θ (0 upright) and spin φ; frames
A = yaw ψ about N.z, B = lean θ about A.x, disk D = spin φ about the axle B.y; the centre
is r·B.z above the contact point (so it stays on the plane: no holonomic constraint is
needed).  Speeds u1..u5 = (ẋ, ẏ, ψ̇, θ̇, φ̇); rolling: the disk's material point at the
contact has zero velocity (two linear nonholonomic constraints, u_I = (ψ̇, θ̇, φ̇)).
Moments of inertia m r²/4 (diameter) and m r²/2 (axle).

Steady turning at lean θ, yaw rate Ω and axle spin s = φ̇ + Ω sin θ satisfies
(Newton–Euler about the centre)  I1 Ω² sin θ cos θ − (I3 + m r²) s Ω cos θ = m g r sin θ;
upright rolling at speed v is stable for v² > g r / 3.
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

R0, G0 = 0.3, 9.81  # the default radius (m) and gravity (m/s²): the threshold below is computed from them


def upright_threshold(r: float = R0, g: float = G0) -> float:
    """The spin φ̇ above which upright rolling is stable: v² > g r / 3 with v = r φ̇."""
    return math.sqrt(g / (3.0 * r))


WHAT_TO_TRY = (
    "Roll it upright: lean θ = 0, yaw rate u3 = ψ̇ = 0, a tiny lean rate u4 = θ̇ (0.05) and the spin "
    f"u5 = φ̇. Upright rolling is stable above the speed v = √(g r/3), i.e. φ̇ > √(g/(3r)) = "
    f"{upright_threshold():.2f} rad/s for r = {R0:g} m: just above it the disk wobbles a little and stays "
    "up; just below it the tiny lean grows into a large wobble. Lean it (θ) and give it a yaw rate u3: "
    "it turns on a circle. The contact point never slips (its violation, below 1e-9 m/s, is the "
    "integrator's error: halve Δt and it falls 16-fold) and no energy is lost. "
    "Watch the contact force: its friction (contact.lateral, the arrow's sideways part) is what turns "
    "the coin — it points to the circle's centre — and the normal force (contact.normal) is m g only "
    "when the coin rolls upright and straight; as it wobbles, it swings above and below m g."
)

# the sliders of the initial values, with what each one is (ranges around the defaults)
INITIAL_CONTROLS = {
    "x": (-2.0, 2.0, "x [m] (contact point)"),
    "y": (-2.0, 2.0, "y [m] (contact point)"),
    "psi": (-2.0, 2.0, "ψ (heading) [rad]"),
    "theta": (-1.8, 2.2, "θ (lean) [rad]"),
    "phi": (-2.0, 2.0, "φ (spin angle) [rad]"),
    "u3": (-6.0, 3.0, "u3 = ψ̇ (yaw rate) [rad/s]"),
    "u4": (-2.0, 2.0, "u4 = θ̇ (lean rate) [rad/s]"),
    "u5": (-12.0, 24.0, "u5 = φ̇ (spin) [rad/s]"),
}


def _model():
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    x, y, psi, th, ph = q = me.dynamicsymbols("x y psi theta phi")
    u = me.dynamicsymbols("u1:6")
    m, r, g = sp.symbols("m r g", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (psi, N.z))
    B = A.orientnew("B", "Axis", (th, A.x))
    D = B.orientnew("D", "Axis", (ph, B.y))
    D.set_ang_vel(N, u[2] * N.z + u[3] * A.x + u[4] * B.y)
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)  # the contact point on the plane
    P.set_vel(N, u[0] * N.x + u[1] * N.y)
    C = P.locatenew("C", r * B.z)  # the disk's centre
    C.set_vel(N, P.vel(N) + (C.pos_from(P)).dt(N).subs({qi.diff(): ui for qi, ui in zip(q, u, strict=True)}))
    disk = me.RigidBody("disk", C, D, m, (me.inertia(B, m * r**2 / 4, m * r**2 / 2, m * r**2 / 4), C))
    # velocity of the disk's material point at the contact: v_C + ω × (P − C)
    v_contact = C.vel(N) + D.ang_vel_in(N).cross(-r * B.z)
    kd = [qi.diff() - ui for qi, ui in zip(q, u, strict=True)]
    energy = disk.kinetic_energy(N) + m * g * r * sp.cos(th)
    return MechanicalModel.from_mechanics(
        "default",
        q=list(q),
        u=list(u),
        kd_eqs=kd,
        bodies=[disk],
        loads=[(C, -m * g * N.z)],
        frame=N,
        params=(m, r, g),
        nonholonomic={"roll_x": v_contact.dot(N.x), "roll_y": v_contact.dot(N.y)},
        u_independent=(u[2], u[3], u[4]),
        energy=energy,
        description="rolling without slipping: the contact point's velocity is zero",
    )


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, cylinder, ground, rot_x, rot_y, rot_z, trace
    from ..symbolic.model import plain_symbols

    x, y, psi, th, ph = plain_symbols("x y psi theta phi")
    r = sp.Symbol("r", positive=True)
    Rb = rot_z(psi) * rot_x(th)
    centre = sp.Matrix([x, y, 0]) + Rb * sp.Matrix([0, 0, r])
    return Visuals(
        frames=(Frame("disk", tuple(centre), Rb * rot_y(ph)),),
        shapes=(
            ground(0),
            cylinder("disk", "disk", r, 0.08 * r, axis="y", color=(200, 160, 40)),
            box("stripe", "disk", (0.95 * r, 0.1 * r, 0.15 * r), (0.475 * r, 0, 0), color=(60, 60, 70)),
            cylinder("hub", "disk", 0.15 * r, 0.12 * r, axis="y", color=(120, 120, 130)),
            trace("contact_path", (x, y, sp.Float(0.003))),
        ),
    )


def _forces(variant: str):
    """The ground's force on the coin at the contact point, in the heading frame A (x: rolling
    direction, y: sideways, z: up).  Friction (longitudinal, lateral) by the multiplier route:
    the rolling constraints are written on the contact point's velocity, v_P · N.x = v_P · N.y = 0,
    so the horizontal force is λ_x N.x + λ_y N.y.  The normal force is non-contributing (the
    centre's height r cos θ is built into the coordinates: no constraint, no λ), so it comes from
    Newton's law on the coin: N = m (g + z̈_C), z̈_C = −r (u̇4 sin θ + u4² cos θ)."""
    import sympy as sp

    from ..declare.forces import Forces, PointForce, multiplier, rate
    from ..symbolic.model import plain_symbols

    x, y, psi, th, u4 = plain_symbols("x y psi theta u4")
    m, r, g = sp.symbols("m r g", positive=True)
    lx, ly = multiplier("roll_x"), multiplier("roll_y")
    zdd = -r * (rate("u4") * sp.sin(th) + u4**2 * sp.cos(th))
    return Forces(
        forces=(
            PointForce(
                "contact",
                at=(x, y, 0),
                components=(
                    lx * sp.cos(psi) + ly * sp.sin(psi),
                    -lx * sp.sin(psi) + ly * sp.cos(psi),
                    m * (g + zdd),
                ),
                frame=sp.Matrix([[sp.cos(psi), -sp.sin(psi), 0], [sp.sin(psi), sp.cos(psi), 0], [0, 0, 1]]),
                labels=("longitudinal", "lateral", "normal"),
                route="multipliers + newton",
                on="the coin, at its contact point",
                description="friction along and across the rolling direction (from the rolling constraints' λ) and "
                "the normal force (Newton's law on the coin: non-contributing in these coordinates)",
            ),
        ),
        scale=0.1,  # m per N: the 1 kg coin's m g is a 1 m arrow, out of the top of the 0.6 m coin
    )


def rolling_disk() -> System:
    return System(
        name="rolling-disk",
        title="Rolling disk (coin)",
        variants=_model,
        parameters={
            "m": Parameter(1.0, 0.0, 100.0, "kg", "mass"),
            "r": Parameter(R0, 0.0, 3.0, "m", "radius"),
            "g": Parameter(G0, 0.0, 30.0, "m/s²", "gravitational acceleration", min_inclusive=True),
        },
        default_initial={"x": 0.0, "y": 0.0, "psi": 0.0, "theta": 0.2, "phi": 0.0, "u3": -1.5, "u4": 0.0, "u5": 6.0},
        default_dt=0.005,
        default_t_final=10.0,
        description="A coin rolling without slipping: steady turning, wobbling, falling.",
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
