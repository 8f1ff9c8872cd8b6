"""IFToMM benchmark A05: the stiff flyball governor.

Published specification: the OpenSim 3.2 implementation of the IFToMM / MBS benchmark
library's problem A05 (RehabEngGroup/MBSbenchmarksInOpenSim, help/benchmarks/
A05_FlyballGovernor.rst): "an example of a stiff mechanical system ... coupler rods are
substituted by spring-damper elements.  Shaft, rods and slider can be modeled as prismatic
bodies": shaft and rods 1.0 × 0.01 × 0.01 m, slider 0.1 × 0.1 × 0.1 m, density 3000 kg/m³,
two point masses of 5 kg, spring stiffness K = 8e5 N/m, damping C = 4e4 N·s/m, rest length
0.5 m, s = 0.5 m, α = 30°, shaft speed 2π rad/s; "The dynamic simulation of the A05
benchmark was executed for 10 s ... s values ... are compared with the values provided as
reference".  Geometry and start as in OpenSim's ``src/A05-FlyballGovernor/createModel.cpp``:
the shaft spins about the vertical z (gravity −9.81 m/s² along z) on a frictionless pivot
at the origin; the rods are hinged at (±0.05, 0, 1) of the shaft, 30° below the
horizontal, each with a 5 kg mass at its far end; the slider (centre at height s on the
shaft, turning with it) carries the springs' ends at (±0.05, 0, s); each spring-damper
joins that point to its rod's midpoint (0.5 m: at rest in the initial position); every
speed but the shaft's starts at 0.

Model: q = (phi, s, b1, b2) — the shaft's angle, the slider's height, the rods' angles
below the horizontal — no constraints (the springs replace the couplers), from
sympy.physics.mechanics.  Acceptance (no published numbers could be read): the shaft's
angular momentum about z is conserved (no moment about the axis acts), the energy never
grows (the dampers only dissipate), the springs stay close to their rest length; s(t) is
reported as the benchmark's quantity.  Stiff: the damped spring modes decay at ~1e4 s⁻¹,
so an explicit integrator needs Δt ≲ 2e-4 s.
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

PARAMETERS = {
    "rho": Parameter(3000.0, 0.0, 1e5, "kg/m³", "density of shaft, rods and slider"),
    "w": Parameter(0.01, 0.0, 1.0, "m", "side of the shaft's and rods' square section"),
    "Lr": Parameter(1.0, 0.0, 10.0, "m", "length of shaft and rods"),
    "ls": Parameter(0.1, 0.0, 1.0, "m", "side of the cubic slider"),
    "mb": Parameter(5.0, 0.0, 1e3, "kg", "each point mass (at a rod's end)"),
    "k": Parameter(8e5, 0.0, 1e9, "N/m", "spring stiffness", min_inclusive=True),
    "c": Parameter(4e4, 0.0, 1e9, "N·s/m", "damping", min_inclusive=True),
    "l0": Parameter(0.5, 0.0, 10.0, "m", "spring rest length"),
    "xab": Parameter(0.1, 0.0, 1.0, "m", "distance between the rods' hinges"),
    "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration (along −z)", min_inclusive=True),
}

WHAT_TO_TRY = (
    "The couplers are springs of 8e5 N/m with dampers of 4e4 N·s/m: nearly rigid, and stiff for an "
    "explicit integrator — try dt = 5e-4 and the run blows up, dt = 1e-4 runs. Spin the shaft faster "
    "(dphi = 10) and the balls fly out and lift the slider; soften the springs (k = 1e3) and watch "
    "them stretch. The angular momentum about the shaft stays constant, the energy only decreases."
)


def model(name: str = "default"):
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    phi, s, b1, b2 = q = list(me.dynamicsymbols("phi s b1 b2"))
    u = list(me.dynamicsymbols("dphi ds db1 db2"))
    rho, w, Lr, ls, mb, k, c, l0, xab, g = sp.symbols("rho w Lr ls mb k c l0 xab g", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    S = N.orientnew("S", "Axis", (phi, N.z))  # the shaft (and the slider)
    S.set_ang_vel(N, u[0] * N.z)
    m_bar = rho * w * w * Lr
    m_sl = rho * ls**3
    Gs = O.locatenew("Gs", Lr / 2 * N.z)
    Gs.set_vel(N, 0)
    shaft = me.RigidBody("shaft", Gs, S, m_bar, (me.inertia(S, 0, 0, m_bar * (2 * w * w) / 12), Gs))
    Gsl = O.locatenew("Gsl", s * N.z)
    Gsl.set_vel(N, u[1] * N.z)
    slider = me.RigidBody("slider", Gsl, S, m_sl, (me.inertia(S, *(3 * [m_sl * 2 * ls**2 / 12])), Gsl))
    bodies, loads = [shaft, slider], [(Gs, -m_bar * g * N.z), (Gsl, -m_sl * g * N.z)]
    spring_len, spring_rate = [], []
    for sign, b, ub in ((1, b1, u[2]), (-1, b2, u[3])):
        # rod frame: its x along the rod (outwards and b below the horizontal), hinge axis ∓S.y
        Rf = S.orientnew(f"R{b}", "Axis", (sign * b, S.y))
        Rf.set_ang_vel(S, sign * ub * S.y)
        A = O.locatenew(f"A{b}", sign * xab / 2 * S.x + Lr * N.z)
        A.v2pt_theory(O, N, S)
        dvec = sign * Rf.x
        Gr = A.locatenew(f"Gr{b}", Lr / 2 * dvec)
        Gr.v2pt_theory(A, N, Rf)
        tip = A.locatenew(f"B{b}", Lr * dvec)
        tip.v2pt_theory(A, N, Rf)
        rod = me.RigidBody(
            f"rod{b}",
            Gr,
            Rf,
            m_bar,
            (me.inertia(Rf, m_bar * 2 * w * w / 12, *(2 * [m_bar * (Lr**2 + w * w) / 12])), Gr),
        )
        ball = me.Particle(f"ball{b}", tip, mb)
        E = Gsl.locatenew(f"E{b}", sign * ls / 2 * S.x)
        E.v2pt_theory(Gsl, N, S)
        r = Gr.pos_from(E)
        length = sp.sqrt(r.dot(r))
        rate = (Gr.vel(N) - E.vel(N)).dot(r) / length
        tension = k * (length - l0) + c * rate  # pulls E and the rod's midpoint together
        loads += [(Gr, -tension * r / length), (E, tension * r / length), (Gr, -m_bar * g * N.z), (tip, -mb * g * N.z)]
        bodies += [rod, ball]
        spring_len.append(length)
        spring_rate.append(rate)
    energy = sum(bd.kinetic_energy(N) for bd in bodies) + sum(
        m * g * P.pos_from(O).dot(N.z) for P, m in ((Gs, m_bar), (Gsl, m_sl))
    )
    for bd in bodies[2:]:
        P = bd.masscenter if hasattr(bd, "masscenter") else bd.point
        energy += bd.mass * g * P.pos_from(O).dot(N.z)
    energy += sum(k * (L_ - l0) ** 2 / 2 for L_ in spring_len)
    Hz = sum((bd.angular_momentum(O, N).dot(N.z) for bd in bodies), sp.S.Zero)
    t = me.dynamicsymbols._t
    return MechanicalModel.from_mechanics(
        name,
        q=q,
        u=u,
        kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)],
        bodies=bodies,
        loads=loads,
        frame=N,
        params=(rho, w, Lr, ls, mb, k, c, l0, xab, g),
        energy=energy,
        outputs={"Hz": Hz, "stretch1": spring_len[0] - l0, "stretch2": spring_len[1] - l0},
        description="stiff flyball governor: shaft, slider, two rods with balls, two spring-dampers",
    )


def initial_state() -> dict[str, float]:
    return {
        "phi": 0.0,
        "s": 0.5,
        "b1": math.pi / 6,
        "b2": math.pi / 6,
        "dphi": 2 * math.pi,
        "ds": 0.0,
        "db1": 0.0,
        "db2": 0.0,
    }


def acceptance(t, x, kernel, p) -> dict[str, float]:
    """The benchmark's quantity and its checks from a trajectory (rows of [q, u]): the
    slider's height s (its range, m), the drift of the axial angular momentum relative to its
    value, the largest energy increase between rows (J; ≤ 0 up to round-off: the dampers only
    dissipate) and the springs' largest stretch (m); ``kernel`` a
    :class:`~nmkane_core.symbolic.reference.ReferenceKernel` of :func:`model`."""
    import numpy as np

    x = np.asarray(x, float)
    out = np.array([kernel.outputs(ti, xi, p) for ti, xi in zip(t, x, strict=True)])  # Hz, stretch1, stretch2
    E = np.array([kernel.energy(ti, xi, p) for ti, xi in zip(t, x, strict=True)])
    return {
        "s_min": float(x[:, 1].min()),
        "s_max": float(x[:, 1].max()),
        "Hz_drift": float(np.abs(out[:, 0] - out[0, 0]).max() / abs(out[0, 0])),
        "energy_increase": float(np.diff(E).max(initial=0.0)),
        "stretch": float(np.abs(out[:, 1:]).max()),
    }


def _visuals():
    import sympy as sp

    from ..declare.visuals import Frame, Visuals, box, ground, rot_z, segments, sphere, trace
    from ..symbolic.model import plain_symbols

    phi, s, b1, b2 = plain_symbols("phi s b1 b2")
    Lr, xab, ls = sp.symbols("Lr xab ls", positive=True)
    R = rot_z(phi)

    def world(v):
        return tuple(R * sp.Matrix(v))

    A1, A2 = world((xab / 2, 0, Lr)), world((-xab / 2, 0, Lr))
    B1 = world((xab / 2 + Lr * sp.cos(b1), 0, Lr - Lr * sp.sin(b1)))
    B2 = world((-xab / 2 - Lr * sp.cos(b2), 0, Lr - Lr * sp.sin(b2)))
    M1 = world((xab / 2 + Lr / 2 * sp.cos(b1), 0, Lr - Lr / 2 * sp.sin(b1)))
    M2 = world((-xab / 2 - Lr / 2 * sp.cos(b2), 0, Lr - Lr / 2 * sp.sin(b2)))
    E1, E2 = world((ls / 2, 0, s)), world((-ls / 2, 0, s))
    return Visuals(
        frames=(Frame("shaft", (0, 0, 0), R), Frame("slider", (0, 0, s), R)),
        shapes=(
            ground(0),
            box("shaft", "shaft", (0.02, 0.02, Lr), (0, 0, Lr / 2), color=(90, 100, 115)),
            box("slider", "slider", (ls, ls, ls), color=(40, 90, 200)),
            segments("rods", [(A1, B1), (A2, B2)], color=(90, 100, 115), thickness=4),
            segments("springs", [(E1, M1), (E2, M2)], color=(90, 160, 60), thickness=2),
            sphere("ball1", 0.06, at=B1, color=(214, 48, 39)),
            sphere("ball2", 0.06, at=B2, color=(214, 48, 39)),
            trace("ball1_path", B1),
        ),
    )


def iftomm_a05() -> System:
    return System(
        name="iftomm-a05",
        title="IFToMM A05: stiff flyball governor",
        variants=model,
        parameters=PARAMETERS,
        default_initial=initial_state(),
        initial_controls={
            "phi": (-3.2, 3.2, "φ [rad] (the shaft's angle)"),
            "s": (0.1, 0.9, "s [m] (the slider's height on the shaft)"),
            "b1": (0.1, 1.4, "β1 [rad] (rod 1's hinge angle)"),
            "b2": (0.1, 1.4, "β2 [rad] (rod 2's hinge angle)"),
            "dphi": (0.0, 20.0, "dphi = φ̇ (the shaft's spin rate) [rad/s]"),
            "ds": (-2.0, 2.0, "ds = ṡ (the slider's speed) [m/s]"),
            "db1": (-5.0, 5.0, "db1 = β̇1 (rod 1's swing rate) [rad/s]"),
            "db2": (-5.0, 5.0, "db2 = β̇2 (rod 2's swing rate) [rad/s]"),
        },
        default_dt=1e-4,
        default_t_final=10.0,
        default_integrator="kutta-merson",
        description="IFToMM benchmark A05: a flyball governor whose couplers are stiff spring-dampers; 10 s.",
        visuals=_visuals,
        what_to_try=WHAT_TO_TRY,
    )
