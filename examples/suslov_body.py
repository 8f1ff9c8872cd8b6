"""The Suslov body — a rigid body turning about a fixed point with a nonholonomic constraint — twice:
oriented by a unit quaternion, and by ZYX Euler angles.  An nmkane systems file.

Load it with ``nmkane run suslov-body --systems examples/suslov_body.py``.

A body turns freely about its centre of mass, except that a blade (or a pair of wheels) forbids
any turning about the body axis e2: ω·e2 = 0 (Suslov 1902; Bloch, *Nonholonomic Mechanics and
Control*, the Suslov problem).  With e2 not a principal axis of inertia — here the product of
inertia I12 couples e1 and e2 — the turning about e3 is unstable: started close to it at
ω3 = Ω, the rates follow ω3 = −Ω tanh(Ω I12 (t − t0)/I11) and
ω1 = √(I33/I11) Ω sech(Ω I12 (t − t0)/I11): the body reverses its spin about e3 (the energy is
kept; the constraint's torque, along e2, does no work).

Started with e3 horizontal, the body's x-axis sweeps through the vertical twice a turn: its ZYX
pitch θ passes ±π/2, the Euler angles' gimbal lock, where their kinematics q̇ = C u blow up
(1/cos θ).  The two systems here are the same body:

* ``suslov-body``: q = (q0, q1, q2, q3), u = (ω1, ω2, ω3, s) — the quaternion of
  ``nmkane_core.declare.rotation``, its norm a holonomic constraint and s its rate: no gimbal
  lock, the run goes through every passage;
* ``suslov-body-zyx``: q = (ψ, θ, φ), u = (ω1, ω2, ω3) — a run stops ``singular`` where the
  kinematics degenerate (or its steps cannot follow the angles' swing near them), and never
  goes on with a wrong orientation.
"""

import math

from nmkane_core import Parameter, System, register
from nmkane_core.declare.rotation import quaternion_from_axis_angle

SPIN = 2 * math.pi  # rad/s: one turn a second about e3, the unstable rotation
NUDGE = 0.01  # rad/s: ω1 at the start, the nudge off it
START = quaternion_from_axis_angle((1.0, 0.0, 0.0), math.pi / 2)  # e3 horizontal (along −y), e1 along x

PARAMETERS = {
    "I11": Parameter(1.0, 0.0, 100.0, "kg·m²", "moment of inertia about the body axis e1"),
    "I22": Parameter(1.2, 0.0, 100.0, "kg·m²", "moment of inertia about e2, the axis it may not turn about"),
    "I33": Parameter(1.0, 0.0, 100.0, "kg·m²", "moment of inertia about e3"),
    "I12": Parameter(0.3, -50.0, 50.0, "kg·m²", "product of inertia of e1 and e2 (0: e2 principal, no reversal)"),
}


def _inertia():
    import sympy as sp

    I11, I22, I33, I12 = sp.symbols("I11 I22 I33 I12", real=True)
    return (I11, I22, I33, I12), sp.Matrix([[I11, I12, 0], [I12, I22, 0], [0, 0, I33]])


def suslov_model(chart: str = "quaternion"):
    """The body with its orientation as a unit quaternion ("quaternion") or ZYX angles ("zyx")."""
    from nmkane_core import MechanicalModel
    from nmkane_core.declare.rotation import quaternion_kinematics, zyx_kinematics

    rot = quaternion_kinematics() if chart == "quaternion" else zyx_kinematics()
    params, I = _inertia()
    w1, w2, w3 = rot.rates
    return MechanicalModel(
        name=chart,
        q=rot.coordinates,
        u=rot.speeds,
        params=params,
        C=rot.C,
        D=rot.D,
        Q=rot.inertia(I),  # with a quaternion: the norm rate's fictitious inertia, which moves nothing
        P=rot.gyroscopic(I),  # −ω × Iω
        nonholonomic={"suslov": w2},  # ω·e2 = 0
        holonomic=rot.holonomic,  # the quaternion's |q|² − 1 = 0
        u_independent=(w1, w3),  # u_D: ω2 (and s)
        q_dependent=rot.coordinates[:1] if chart == "quaternion" else (),  # q0 from |q| = 1
        energy=rot.kinetic_energy(I),
        outputs={f"R{i + 1}{j + 1}": rot.R[i, j] for i in range(3) for j in range(3)},
    )


def suslov_visuals():
    """The body as a slab on its three axes, the tip of e1 traced (it sweeps through the vertical)."""
    from nmkane_core.declare.rotation import quaternion_kinematics
    from nmkane_core.declare.visuals import Frame, Visuals, box, rod, trace

    R = quaternion_kinematics().R
    return Visuals(
        frames=(Frame("body", (0, 0, 0), R),),
        shapes=(
            box("slab", "body", (1.0, 0.15, 0.6), color=(70, 110, 170)),
            rod("e1", "body", (0, 0, 0), (0.8, 0, 0), 0.03, color=(210, 60, 40)),
            rod("e2 (blade)", "body", (0, 0, 0), (0, 0.5, 0), 0.03, color=(60, 160, 80)),
            rod("e3", "body", (0, 0, 0), (0, 0, 0.5), 0.03, color=(60, 60, 200)),
            trace("tip of e1", tuple(R[:, 0] * 0.8)),
        ),
    )


DESCRIPTION = "A body turning about a fixed point that may not turn about its axis e2 (ω·e2 = 0): it reverses its spin."
register(
    System(
        name="suslov-body",
        title="Suslov body (unit quaternion)",
        variants=lambda: suslov_model("quaternion"),
        parameters=PARAMETERS,
        default_initial={**dict(zip(("q0", "q1", "q2", "q3"), START, strict=True)), "w1": NUDGE, "w3": SPIN},
        default_dt=0.001,
        default_t_final=8.0,
        description=DESCRIPTION + " Its orientation is a unit quaternion: no gimbal lock.",
        visuals=suslov_visuals,
    )
)
register(
    System(
        name="suslov-body-zyx",
        title="Suslov body (ZYX Euler angles)",
        variants=lambda: suslov_model("zyx"),
        parameters=PARAMETERS,
        default_initial={"psi": 0.0, "theta": 0.0, "phi": math.pi / 2, "w1": NUDGE, "w3": SPIN},
        default_dt=0.001,
        default_t_final=8.0,
        description=DESCRIPTION + " Its orientation is three Euler angles: singular where θ = ±π/2.",
    )
)
