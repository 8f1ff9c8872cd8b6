"""IFToMM benchmark A04: Bricard's mechanism (an over-constrained loop), and its planar
cousin, the parallelogram with three cranks.

Published specification: the OpenSim 3.2 implementation of the IFToMM / MBS benchmark
library's problem A04 (RehabEngGroup/MBSbenchmarksInOpenSim, help/benchmarks/
A04_BricardsMechanism.rst): "Bricard's mechanism ... is an example of over-constrained
system.  Grübler's formula results in no degrees of freedom, however, the particular
orientation of the revolute pairs results in a system with one degree of freedom ... The
system is composed of five rods with square cross section and six revolute joints.
Gravity is acting towards the negative y direction."  Rods: 1.0 kg, 1.0 m, square cross
section 0.1 m; simulated for 10 s in 0.258 s of CPU; evaluated by "the total mechanical
energy variation from the initial condition" (zero in theory) and the displacement of
point P3.  The geometry is that of the OpenSim model (``src/A04-BricardsMechanism/
createModel.cpp``), also used by simEngine3D (``simEngine3D_BricardMechanism.m``): five
rods on the edges of a unit cube and a sixth "rod", the ground edge from (0, 0, L) to the
origin —

    J1 (0, 0, 0) axis y — rod 1 along +x — J2 (L, 0, 0) axis z — rod 2 along −y —
    J3 (L, −L, 0) axis x — rod 3 along +z — J4 (L, −L, L) axis y — rod 4 along −x —
    J5 (0, −L, L) axis z — rod 5 along +y — J6 (0, 0, L) axis x (to the ground)

each joint axis perpendicular to both rods it joins; P3 = J3, the end of rod 2.  The
OpenSim model starts at rest in this configuration (no initial speed is set: every pin's
default angle and speed are 0).  The IFToMM text of A04 itself could not be read (only its
title page): the duration used is OpenSim's 10 s.

Model: the five joint angles q1..q5 of the open chain J1..J5 (relative angles, q̇ = u), and
the closure at J6 written with all its equations — rod 5's end at (0, 0, L) (3 equations)
and rod 5's J6 axis parallel to the ground x axis (2 equations): 5 equations of which only
4 are independent (1 degree of freedom).  ``u_independent`` = (u1,) declares the 5 with
one independent speed; the rank (4) is checked numerically.

The planar cousin (:func:`parallelogram_model`): three parallel cranks pinned to the
ground at (0, 0), (a, 0), (2a, 0) and one coupler of length 2a pinned to the three tips;
with all four closure equations (two per extra tip) on four coordinates: rank 3, one
degree of freedom — the classic over-constrained linkage.  Its motion is known exactly:
every crank turns by the same θ(t), a pendulum with I = 3 m L² (three cranks of m L²/3 and
the coupler of mass 2m translating with the tips) and K = 3.5 m g L: I θ̈ = −K cos θ.
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

#: OpenSim 3.2 CPU time for A04 over 10 s (RehabEngGroup/MBSbenchmarksInOpenSim,
#: help/benchmarks/A04_BricardsMechanism.rst: "required 0.258 seconds", Intel i5-4570)
OPENSIM_CPU_S = 0.258

PARAMETERS = {
    "L": Parameter(1.0, 0.0, 100.0, "m", "length of every rod"),
    "m": Parameter(1.0, 0.0, 1e4, "kg", "mass of every rod"),
    "a": Parameter(0.1, 0.0, 10.0, "m", "side of the rods' square cross section (OpenSim: 0.1 m)", min_inclusive=True),
    "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration (along −y)", min_inclusive=True),
}

WHAT_TO_TRY = (
    "Count: 5 rods and 6 hinges leave, by Grübler's formula, no freedom at all — yet the mechanism "
    "moves, because its hinge axes are special. The constraint equations are redundant: 5 closure "
    "equations, only 4 independent: ask for solve paper and the run is refused (no choice of dependent "
    "speeds makes J2 square), the rank-robust solve keeps 4 and drops the dependent one. Released from "
    "rest it swings under gravity forever (no dissipation: the energy drift is the solver's). Give it "
    "a push (u1 = 2) and watch P3. Push harder (u1 = 5): the later Runge–Kutta stages of a step "
    "leave the constraints by the step's error, where the redundant equation disagrees with the "
    "others; the run judges the equations at the states it accepts and goes on, on the motion a "
    "ten times finer step gives."
)


#: the sliders of the web page: the independent values (the other joints follow from the closure;
#: beyond these ranges the completion can land on another assembly of the loop)
INITIAL_CONTROLS = {
    "q1": (-0.5, 1.5, "q1 [rad] (joint J1's angle about y; the other four joints follow from the closure)"),
    "u1": (-3.0, 3.0, "u1 = q̇1 (joint J1's rate) [rad/s]"),
}


# ---------------------------------------------------------------------------- Bricard (A04)
#: joint axes (in the frame of the rod before it: all frames coincide with the ground's in
#: the initial configuration) and the direction of each rod from its joint
JOINT_AXES = ("y", "z", "x", "y", "z")
ROD_DIRECTIONS = ((1, 0, 0), (0, -1, 0), (0, 0, 1), (-1, 0, 0), (0, 1, 0))


def bricard_model(name: str = "default", partition: bool = True, redundant: bool = True):
    """Bricard's mechanism: 5 joint angles, the J6 closure with its 5 equations (rank 4),
    through sympy.physics.mechanics (KanesMethod on the open chain J1..J5).

    ``redundant=False`` leaves out ``J6_axis_y`` (the equation the equilibrated QR finds
    dependent at the start): the classic non-redundant declaration, for comparison."""
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    q = list(me.dynamicsymbols("q1:6"))
    u = list(me.dynamicsymbols("u1:6"))
    L, m, a, g = sp.symbols("L m a g", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    frame, point = N, O
    bodies, loads, joints = [], [], [O]
    for k in range(5):
        axis = getattr(frame, JOINT_AXES[k])
        F = frame.orientnew(f"R{k + 1}", "Axis", (q[k], axis))
        F.set_ang_vel(frame, u[k] * axis)
        d = sum((c * v for c, v in zip(ROD_DIRECTIONS[k], (F.x, F.y, F.z), strict=True)), 0 * F.x)
        G = point.locatenew(f"G{k + 1}", L / 2 * d)
        G.v2pt_theory(point, N, F)
        end = point.locatenew(f"J{k + 2}", L * d)
        end.v2pt_theory(point, N, F)
        # a square bar along its axis d: m(a² + a²)/12 about d, m(L² + a²)/12 across
        I = [m * (a**2 + a**2) / 12 if c else m * (L**2 + a**2) / 12 for c in ROD_DIRECTIONS[k]]
        bodies.append(me.RigidBody(f"rod{k + 1}", G, F, m, (me.inertia(F, *I), G)))
        loads.append((G, -m * g * N.y))
        joints.append(end)
        frame, point = F, end
    gap = joints[5].pos_from(O).to_matrix(N)
    x_axis = frame.x.to_matrix(N)  # rod 5's J6 axis (its x), which must stay along the ground's x
    closures = {
        "J6_x": gap[0],
        "J6_y": gap[1],
        "J6_z": gap[2] - L,
        "J6_axis_y": x_axis[1],
        "J6_axis_z": x_axis[2],
    }
    if not redundant:
        del closures["J6_axis_y"]
    energy = sum(b.kinetic_energy(N) for b in bodies) + sum(m * g * G.pos_from(O).dot(N.y) for G, _ in loads)
    p3 = joints[2].pos_from(O).to_matrix(N)
    t = me.dynamicsymbols._t
    return MechanicalModel.from_mechanics(
        name,
        q=q,
        u=u,
        kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)],
        bodies=bodies,
        loads=loads,
        frame=N,
        params=(L, m, a, g),
        holonomic=closures,
        u_independent=(u[0],) if partition else (),
        q_dependent=tuple(q[1:]) if partition else (),
        energy=energy,
        outputs={"P3_x": p3[0], "P3_y": p3[1], "P3_z": p3[2]},
        description="Bricard's mechanism: 5 closure equations at J6, 4 independent (1 degree of freedom)",
    )


# ------------------------------------------------------------- the redundant parallelogram
def parallelogram_model(name: str = "default", redundant: bool = True, partition: bool = True):
    """Three cranks (th0, th1, th2) on ground pivots (0, 0), (L, 0), (2L, 0) and one coupler
    (ph) of length 2L pinned to crank 0's tip; closures at the tips of cranks 1 and 2.

    ``redundant=True`` declares all four closure equations (rank 3); ``False`` only three
    (tip 1 both ways, tip 2 along y: the classic non-redundant choice)."""
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols
    from .iftomm_common import Body, rigid_bodies_QP

    th = plain_symbols("th0 th1 th2")
    ph = plain_symbols("ph")[0]
    q = (*th, ph)
    u = plain_symbols("dth0 dth1 dth2 dph")
    L, m, g = sp.symbols("L m g", positive=True)
    tip = [(k * L + L * sp.cos(th[k]), L * sp.sin(th[k]), 0) for k in range(3)]
    bodies = [
        Body(
            (k * L + L / 2 * sp.cos(th[k]), L / 2 * sp.sin(th[k]), 0),
            m,
            omega=(0, 0, u[k]),
            inertia=sp.diag(0, 0, m * L**2 / 12),
            force=(0, -m * g, 0),
        )
        for k in range(3)
    ]
    bodies.append(
        Body(
            (tip[0][0] + L * sp.cos(ph), tip[0][1] + L * sp.sin(ph), 0),
            2 * m,
            omega=(0, 0, u[3]),
            inertia=sp.diag(0, 0, 2 * m * (2 * L) ** 2 / 12),
            force=(0, -2 * m * g, 0),
        )
    )
    closures = {}
    for k in (1, 2):
        closures[f"tip{k}_x"] = tip[0][0] + k * L * sp.cos(ph) - tip[k][0]
        closures[f"tip{k}_y"] = tip[0][1] + k * L * sp.sin(ph) - tip[k][1]
    if not redundant:
        del closures["tip2_x"]
    Q, P, T = rigid_bodies_QP(bodies, q, u)
    V = sum(b.mass * g * b.r[1] for b in bodies)
    return MechanicalModel(
        name=name,
        q=q,
        u=u,
        params=(L, m, g),
        C=sp.eye(4),
        D=sp.zeros(4, 1),
        Q=Q,
        P=P,
        holonomic=closures,
        u_independent=(u[0],) if partition else (),
        q_dependent=(th[1], th[2], ph) if partition else (),
        energy=T + V,
        outputs={"xB0": L * sp.cos(th[0]), "yB0": L * sp.sin(th[0])},
        description="three parallel cranks, one coupler: "
        + ("4 closure equations, 3 independent" if redundant else "3 closure equations"),
    )


def parallelogram_state(theta0: float = math.pi / 2, vx_B0: float = 1.0, L: float = 1.0) -> dict[str, float]:
    w = -vx_B0 / (L * math.sin(theta0))
    return {"th0": theta0, "th1": theta0, "th2": theta0, "ph": 0.0, "dth0": w, "dth1": w, "dth2": w, "dph": 0.0}


def parallelogram_constants(L: float = 1.0, m: float = 1.0, g: float = 9.81) -> tuple[float, float]:
    """(I, K) of the exact motion I θ̈ = −K cos θ (all cranks alike, coupler translating)."""
    return 3 * m * L**2, 3.5 * m * g * L


def bricard_points(q, L):
    """The joints J1..J6 (model axes, y up) as sympy expressions of the joint angles."""
    import sympy as sp

    from ..declare.visuals import rot_x, rot_y, rot_z

    rot = {"x": rot_x, "y": rot_y, "z": rot_z}
    R, point, points = sp.eye(3), sp.zeros(3, 1), [sp.zeros(3, 1)]
    for k in range(5):
        R = R * rot[JOINT_AXES[k]](q[k])
        point = point + R * sp.Matrix(ROD_DIRECTIONS[k]) * L
        points.append(point)
    return points


def acceptance(t, x, kernel, p) -> dict[str, float]:
    """The benchmark's quantities from a trajectory (rows of [q, u]): the largest energy
    drift (J) and P3's path (its range along each axis, m), with ``kernel`` a
    :class:`~nmkane_core.symbolic.reference.ReferenceKernel` of :func:`bricard_model`."""
    import numpy as np

    E = np.array([kernel.energy(ti, xi, p) for ti, xi in zip(t, x, strict=True)])
    P3 = np.array([kernel.outputs(ti, xi, p) for ti, xi in zip(t, x, strict=True)])
    return {
        "energy_drift": float(np.abs(E - E[0]).max()),
        **{f"P3_{a}_range": float(np.ptp(P3[:, i])) for i, a in enumerate("xyz")},
    }


def _visuals():
    import sympy as sp

    from ..declare.visuals import Visuals, segments, sphere, trace
    from ..symbolic.model import plain_symbols

    q = plain_symbols("q1:6")
    L = sp.Symbol("L", positive=True)

    def w(v):  # model axes (gravity along −y) → the viewer's (z up): a quarter turn about x
        return (v[0], -v[2], v[1])

    J = [w(P) for P in bricard_points(q, L)]
    return Visuals(
        shapes=(
            segments("rods", [(J[k], J[k + 1]) for k in range(5)], color=(40, 90, 200), thickness=5),
            segments("ground_rod", [(J[5], J[0])], color=(80, 80, 80), thickness=5),
            sphere("P3", 0.05 * L, at=J[2], color=(214, 48, 39)),
            trace("P3_path", J[2]),
        ),
        view=(1.0, -1.0, 0.6),
    )


def iftomm_a04() -> System:
    """The catalogue entry (``iftomm-a04``), declared with all five closure equations: no
    partition has a square J2 (n − p = 4 < m = 5), so its kernel carries the rank-robust solve
    (``solve`` auto or robust; docs/closed-loops.md §7)."""
    return System(
        name="iftomm-a04",
        title="IFToMM A04: Bricard's mechanism",
        variants=bricard_model,
        parameters=PARAMETERS,
        default_initial={f"q{k}": 0.0 for k in range(1, 6)} | {f"u{k}": 0.0 for k in range(1, 6)},
        initial_controls=INITIAL_CONTROLS,
        default_dt=1e-3,
        default_t_final=10.0,
        default_integrator="kutta-merson",
        default_gamma1=-20.0,
        default_gamma2=-100.0,
        # its five closures stay consistent to round-off without a projection (|ΔE| 7.6e-13 J over
        # 10 s; with yoon, the redundant default, 4.1e-12): the benchmark's numbers as published
        default_projection="none",
        description="IFToMM benchmark A04: five rods, six hinges, one degree of freedom that Grübler's count misses.",
        visuals=_visuals,
        what_to_try=WHAT_TO_TRY,
    )
