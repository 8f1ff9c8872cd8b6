"""The rattleback (celt, wobblestone): a semi-ellipsoidal body whose inertia axes are turned a
little from its geometric axes, rolling without slipping on a horizontal plane under gravity.
Spun one way it rocks, stops and spins the other way.

The parameters are Kane & Levinson's ("Realistic mathematical modeling of the rattleback",
Int. J. Non-Linear Mech. 17 (1982) 175):
the ellipsoid's semi-axes a = 0.20 m, b = 0.03 m, c = 0.02 m; the mass centre G a distance
h = 0.01 m below the ellipsoid's centre O; mass m = 1 kg, g = 9.81 m/s²; the inertia about G
in the geometric axes A = 2·10⁻⁴, B = 1.6·10⁻³, C = 1.7·10⁻³ kg·m² with the tensor's xy
element D = −2·10⁻⁵ kg·m².  Here the inertia is declared by its principal moments I1, I2, I3
and the angle δ of the principal axes from the geometric ones, about the body's vertical:
[[A, D], [D, B]] = R_z(δ) diag(I1, I2) R_z(δ)ᵀ, so K&L's numbers are
I1 = (A + B)/2 − √(((B − A)/2)² + D²) = 1.99714·10⁻⁴, I2 = 1.600286·10⁻³ kg·m²,
δ = ½ atan2(−2D, B − A) = 0.0142818 rad (0.818°).  K&L's initial state: roll and pitch 0.5°,
spin −5 rad/s about their body axis 3.  Their axis 3 points down, into the plane; read in this
model's axes (z up) the same numbers — D = −2·10⁻⁵ kg·m², spin u6 = −5 rad/s, clockwise seen
from above — give the mirror image of their motion, which reverses at the same time.
Dissipation-free, the body rocks harder and harder, its spin flickers through zero between
t = 2.68 s and 2.86 s, and its heading ψ turns round — the reversal — at t = 2.815 s, as the
independent reference gives (`rattleback_oracle`: KanesMethod in minimal coordinates + scipy).

Model (nonminimal, the contact written by `nmkane_core.declare.contact`): a free rigid body —
G at (x, y, z), rotation R = R_z(ψ) R_x(θ) R_y(φ) (yaw ψ, roll θ about the yawed x, pitch φ
about the body's y), speeds u1..u3 = G's velocity (world), u4..u6 = the angular velocity in
body axes — so Q = diag(m, m, m, I_G) is constant; the ellipsoid (about O = G + h·body z) stays
on the plane (holonomic ``on_plane``: z − √(a²μ1² + b²μ2² + c²μ3²) + h μ3 = 0, μ = Rᵀe_z) and
its contact point does not slip (``roll_x``, ``roll_y``).  u_I = (u4, u5, u6), z is solved
from the height.  Output ``spin``: the angular velocity's vertical component ω·e_z.
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

KL = dict(A=2e-4, B=1.6e-3, C=1.7e-3, D=-2e-5)  # Kane & Levinson's inertia about G, kg·m²


def principal(A: float, B: float, D: float) -> tuple[float, float, float]:
    """(I1, I2, δ) of the horizontal inertia [[A, D], [D, B]] = R_z(δ) diag(I1, I2) R_z(δ)ᵀ."""
    mean, half = (A + B) / 2, math.hypot((B - A) / 2, D)
    return mean - half, mean + half, 0.5 * math.atan2(-2 * D, B - A)


I1_KL, I2_KL, DELTA_KL = principal(KL["A"], KL["B"], KL["D"])
TILT = math.radians(0.5)  # K&L's initial roll and pitch
REVERSAL_T = 2.815  # s: when the heading turns round from K&L's initial state (the oracle's 2.81503)

WHAT_TO_TRY = (
    "Spun clockwise (u6 = ω3 = −5 rad/s, seen from above) from a tilt of 0.5° in roll and pitch, it "
    "starts to rock, harder and harder; from t ≈ 2.7 s its spin (the output spin, ω·e_z) flickers "
    f"through zero, its heading ψ turns round at t ≈ {REVERSAL_T:.3f} s, and by t = 5 s it spins "
    "counterclockwise at about 4 rad/s. Spun counterclockwise (u6 = +5) it keeps turning that way. "
    "The reason is δ, the angle between its inertia axes and its geometric axes (0.8°): set δ = 0 and "
    "it keeps either spin; set δ = −0.0143 and the roles swap. Nothing is lost — there is no friction "
    "in this model, the energy drift stays below 1e-6 J — so the spin's energy goes into rocking and "
    "back: run 30 s and it turns back again at t ≈ 17.3 s. Watch the normal force (contact.normal): "
    "m g = 9.81 N at rest, it swings between about 2 and 70 N while the body rocks."
)

INITIAL_CONTROLS = {
    "x": (-1.0, 1.0, "x [m] (mass centre)"),
    "y": (-1.0, 1.0, "y [m] (mass centre)"),
    "psi": (-3.2, 3.2, "ψ (yaw) [rad]"),
    "theta": (-0.2, 0.2, "θ (roll, about the long axis) [rad]"),
    "phi": (-0.1, 0.1, "φ (pitch) [rad]"),
    "u4": (-5.0, 5.0, "u4 = ω1 (roll rate, body x) [rad/s]"),
    "u5": (-5.0, 5.0, "u5 = ω2 (pitch rate, body y) [rad/s]"),
    "u6": (-10.0, 10.0, "u6 = ω3 (spin, about the body's vertical axis) [rad/s]"),
}


def _frame():
    """The symbols, R and the contact (sympy): shared by the model, the visuals and the forces."""
    import sympy as sp

    from ..declare.contact import ellipsoid, rolling_contact
    from ..declare.visuals import rot_x, rot_y, rot_z
    from ..symbolic.model import plain_symbols

    q = plain_symbols("x y z psi theta phi")
    u = plain_symbols("u1:7")
    a, b, c = sp.symbols("a b c", positive=True)
    h = sp.Symbol("h", real=True)
    R = rot_z(q[3]) * rot_x(q[4]) * rot_y(q[5])
    contact = rolling_contact(
        ellipsoid(a, b, c, centre=(0, 0, h)),
        R,
        q[:3],
        u[:3],
        body_angular_velocity=u[3:],
        names=("roll_x", "roll_y", "on_plane"),
    )
    return q, u, (a, b, c, h), R, contact


def _model():
    import sympy as sp

    from ..symbolic.model import MechanicalModel

    q, u, (a, b, c, h), _, contact = _frame()
    m, g, I1, I2, I3 = sp.symbols("m g I1 I2 I3", positive=True)
    delta = sp.Symbol("delta", real=True)
    cd, sd = sp.cos(delta), sp.sin(delta)
    inertia = sp.Matrix(
        [
            [I1 * cd**2 + I2 * sd**2, (I1 - I2) * sd * cd, 0],
            [(I1 - I2) * sd * cd, I1 * sd**2 + I2 * cd**2, 0],
            [0, 0, I3],
        ]
    )
    w = sp.Matrix(u[3:])
    sth, cth, sph, cph = sp.sin(q[4]), sp.cos(q[4]), sp.sin(q[5]), sp.cos(q[5])
    C = sp.zeros(6, 6)  # q̇ = C u: ẋ, ẏ, ż = u1..u3; the ZXY angles' rates from the body rates
    C[0, 0] = C[1, 1] = C[2, 2] = 1
    C[3, 3], C[3, 5] = -sph / cth, cph / cth  # ψ̇ = (cos φ ω3 − sin φ ω1)/cos θ
    C[4, 3], C[4, 5] = cph, sph  # θ̇ = cos φ ω1 + sin φ ω3
    C[5, 3], C[5, 4], C[5, 5] = sph * sth / cth, 1, -cph * sth / cth  # φ̇ = ω2 − sin θ ψ̇
    energy = m / 2 * (u[0] ** 2 + u[1] ** 2 + u[2] ** 2) + (w.T * inertia * w)[0] / 2 + m * g * q[2]
    return MechanicalModel(
        q=q,
        u=u,
        params=(m, g, a, b, c, h, I1, I2, I3, delta),
        C=C,
        D=sp.zeros(6, 1),
        Q=sp.diag(m, m, m, inertia),
        P=sp.Matrix([0, 0, -m * g, *(-w.cross(inertia * w))]),
        holonomic=contact.height,
        nonholonomic=contact.no_slip,
        u_independent=u[3:],
        q_dependent=(q[2],),
        energy=energy,
        outputs={"spin": (contact.up.T * w)[0]},
        description="rolling without slipping: the ellipsoid's lowest point on the plane, its velocity zero",
    )


def _hull(a, b, c, h, slices: int = 12):
    """Boxes stacked along the long axis under the deck (body frame): the semi-ellipsoid, stepped."""
    from ..declare.visuals import box

    out = []
    for k in range(slices):
        x0, x1 = -1 + 2 * k / slices, -1 + 2 * (k + 1) / slices  # in units of a
        outer = max(abs(x0), abs(x1))
        if outer >= 1:
            outer = 1 - 0.5 / slices
        mid = (x0 + x1) / 2
        depth = 0.97 * math.sqrt(1 - outer**2)
        width = 0.8 * math.sqrt(1 - mid**2)
        size = (2 * a / slices, 2 * b * width, c * depth)
        out.append(box(f"hull{k}", "body", size, (mid * a, 0, h - c * depth / 2), color=(176, 120, 60)))
    return out


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, ground, polyline, trace

    q, _, (a, b, c, h), R, contact = _frame()
    origin = sp.Matrix(q[:3])

    def world(p):
        return tuple(origin + R * sp.Matrix(p))

    angles = [sp.pi * k / 24 for k in range(49)]
    half = angles[:25]  # 0 … π: the lower half
    lines = (
        polyline("deck_rim", [world((a * sp.cos(t), b * sp.sin(t), h)) for t in angles], (90, 60, 30), 2.0),
        polyline("keel", [world((a * sp.cos(t), 0, h - c * sp.sin(t))) for t in half], (90, 60, 30), 2.0),
        polyline("rib", [world((0, b * sp.cos(t), h - c * sp.sin(t))) for t in half], (90, 60, 30), 2.0),
    )
    p = contact.point
    return Visuals(
        frames=(Frame("body", tuple(origin), R),),
        shapes=(
            ground(0),
            *_hull(a, b, c, h),
            box("deck", "body", (1.9 * a, 1.4 * b, 0.08 * c), (0, 0, h), color=(214, 170, 96)),
            box("nose", "body", (0.3 * a, 1.0 * b, 0.1 * c), (0.8 * a, 0, h + 0.05 * c), color=(200, 50, 40)),
            *lines,
            trace("contact_path", (p[0], p[1], sp.Float(0.001))),
        ),
        view=(1.0, -1.2, 0.9),
    )


def _forces(variant: str):
    """The plane's force at the contact point, world axes: friction from the no-slip
    constraints' multipliers, the normal force from the height constraint's."""
    from ..declare.forces import Forces

    contact = _frame()[4]
    return Forces(forces=(contact.force("contact", on="the rattleback, at its contact point"),), scale=0.004)


def rattleback() -> System:
    return System(
        name="rattleback",
        title="Rattleback (celt)",
        variants=_model,
        parameters={
            "m": Parameter(1.0, 0.0, 100.0, "kg", "mass"),
            "g": Parameter(9.81, 0.0, 30.0, "m/s²", "gravitational acceleration", min_inclusive=True),
            "a": Parameter(0.2, 0.0, 1.0, "m", "semi-axis of the ellipsoid along the body x (long)"),
            "b": Parameter(0.03, 0.0, 1.0, "m", "semi-axis along the body y"),
            "c": Parameter(0.02, 0.0, 1.0, "m", "semi-axis along the body z (vertical at rest)"),
            "h": Parameter(0.01, -0.5, 0.5, "m", "the mass centre below the ellipsoid's centre", min_inclusive=True),
            "I1": Parameter(I1_KL, 0.0, 1.0, "kg·m²", "principal moment of inertia about G, near the long axis"),
            "I2": Parameter(I2_KL, 0.0, 1.0, "kg·m²", "principal moment of inertia about G, near the body y"),
            "I3": Parameter(KL["C"], 0.0, 1.0, "kg·m²", "moment of inertia about G, vertical axis"),
            "delta": Parameter(
                DELTA_KL, -0.5, 0.5, "rad", "angle of the inertia axes from the geometric axes, about the vertical"
            ),
        },
        default_initial={"x": 0.0, "y": 0.0, "psi": 0.0, "theta": TILT, "phi": TILT, "u4": 0, "u5": 0, "u6": -5.0},
        default_dt=0.0005,
        default_t_final=5.0,
        description="A semi-ellipsoid with skewed inertia axes rolling without slipping: spun one way, it reverses.",
        visuals=_visuals,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
    )
