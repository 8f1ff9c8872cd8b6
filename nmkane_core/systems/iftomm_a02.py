"""IFToMM benchmark A02: the N-four-bar mechanism (N parallelogram windows), a mechanism
that passes through singular positions.

Published specification (IFToMM / MBS benchmark library, problem A02, M. González 2005,
http://lim.ii.udc.es/mbsbenchmark/dist/A02/A02_specification.xml): "The one
degree-of-freedom assembly of N four-bar linkages is composed by 2N+1 links of 1 m length
with a uniformly distributed mass of 1 kg.  The system is under gravity effects (9.81 N/kg
acting in the negative y direction) ... When the mechanism reaches the horizontal
position, the number of degrees of freedom instantaneously increases from 1 to N+1.  The
analysis to be performed is a dynamic simulation with a duration of 20 s.  Initially, the
system (particularized for N=40) is in the position shown in the figure, and the velocity
of the x-coordinate of point B0 is 1 m/s."  Reference quantity: position and velocity of
B0; allowed errors 1e-1 (low) and 1e-3 (high precision).  The OpenSim 3.2 implementation
(RehabEngGroup/MBSbenchmarksInOpenSim, ``src/A02-NFourBarMechanism``) runs N = 2 for 10 s
in 0.455 s of CPU; it and simEngine3D (``simEngine3D_n4BarMechanism.m``) start with the
cranks vertical (all pin angles 0, the crank speed −1 rad/s, so ẋ_B0 = +1 m/s): that is the
default initial state here.  (The closed-loop issue's text says "started at 45°"; that
start is ``initial_state(N, theta0=pi/4)`` — any start on the parallelogram branch has the
exact solution below.)

Model (holonomic loop closures, absolute angles so that every expression is local):

* cranks k = 0..N, pinned to the ground at A_k = (k L, 0): angle ``th{k}`` from +x;
* couplers k = 1..N, pinned to the tip B_{k−1} of crank k−1: angle ``ph{k}``;
* closure of window k: coupler k's right end is crank k's tip B_k (two equations
  ``close{k}_x``, ``close{k}_y``): 2N holonomic constraints on 2N+1 coordinates.

Where the cranks are horizontal (θ = 0 or π) every ``close{k}_x`` row of ∂ψ/∂q vanishes: the
rank of the constraint Jacobian drops from 2N to N (1 → N+1 degrees of freedom), whatever
partition one picks.  Speeds are the angle rates (``dth{k}``, ``dph{k}``); the partition
declared (u_I = dth0) is the paper's one and serves until the first horizontal passage;
the rank-robust solve of :mod:`nmkane_core.symbolic.reference` needs none.

Exact motion (the acceptance oracle): on the parallelogram branch every crank turns by the
same θ(t) and the couplers stay horizontal, so θ obeys one pendulum equation
I θ̈ = −K cos θ with I = (N+1) m L²/3 + N m L² and K = (N+1) m g L/2 + N m g L
(:func:`exact_motion`, integrated to 1e-13).
"""

from __future__ import annotations

import math

from ..declare.system import Parameter, System

PARAMETERS = {
    "L": Parameter(1.0, 0.0, 100.0, "m", "length of every link (and the ground spacing of the cranks)"),
    "m": Parameter(1.0, 0.0, 1e4, "kg", "mass of every link (uniform rod)"),
    "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration (along −y)", min_inclusive=True),
}

#: OpenSim 3.2 CPU time for N = 2 over 10 s (RehabEngGroup/MBSbenchmarksInOpenSim,
#: help/benchmarks/A02_N_FourBarMechanism.rst: "required 0.455 seconds", Intel i5-4570)
OPENSIM_CPU_S = 0.455

WHAT_TO_TRY = (
    "Watch the cranks pass the horizontal (ten times in 10 s: they start at the top and turn round "
    "and round). There every window can fold either way — a bifurcation — and the constraint "
    "Jacobian loses rank: 1 degree of freedom becomes N+1 for an instant. The defaults (solve auto, "
    "Yoon projection, dt = 1e-3) keep B0 on the exact parallelogram motion. Take the projection away "
    "(projection none): the run still projects the few steps that come near a passage (the summary "
    'counts them) and stays on it. Untick "Project near singular positions" too and let the step '
    "adapt (integrator kutta-merson-adaptive): nothing holds "
    "the cranks together any more (th2 − th0 drifts to 1e-7 rad), and the step control closes in on "
    "the singular position but cannot cross it. With solve paper the fixed partition's J2 becomes "
    "singular at t = 0.714 s and the run stops; with solve auto the solve alternates between the "
    "partition and the rank-robust solve as the steps shrink, and the run ends at the same instant "
    "(the step size fell below its minimum): off the branch, the equations do not say which way the "
    "windows fold. With no projection at all at dt = 1e-4 the asymmetry grows at each passage: after "
    "10 s B0 is 3 mm off the parallelogram motion and the energy has drifted by 1e-2 J (with it: "
    "1e-11 m and 1e-11 J). Start lower (th0 = 0.785) and the cranks "
    "swing instead of turning."
)

#: the sliders of the web page: the independent values (the other links follow from the closures)
INITIAL_CONTROLS = {
    "th0": (0.1, 3.0, "th0 [rad] (the cranks' angle from +x; π/2: vertical, the benchmark's start)"),
    "dth0": (-3.0, 3.0, "dth0 = θ̇0 (the cranks' rate; ẋ_B0 = −L sin θ0 · θ̇0) [rad/s]"),
}


def names(N: int) -> tuple[list[str], list[str]]:
    """Coordinate and speed names: cranks th0..thN, couplers ph1..phN."""
    q = [f"th{k}" for k in range(N + 1)] + [f"ph{k}" for k in range(1, N + 1)]
    return q, ["d" + s for s in q]


def model(
    N: int = 2, name: str = "default", partition: bool = True, via: str = "bodies", coordinates: str = "absolute"
):
    """The N-four-bar as a :class:`MechanicalModel`.

    ``via="bodies"``: Q and P built from the rods' sparse Jacobians
    (:func:`.iftomm_common.rigid_bodies_QP`, linear in N: the benchmark's N = 40 in seconds);
    ``via="mechanics"``: the same rods through sympy.physics.mechanics' KanesMethod
    (:meth:`MechanicalModel.from_mechanics`; about N² work, minutes at N = 40) — the tests
    check that both give the same model.  ``partition=False`` leaves u_independent and
    q_dependent out (the library chooses).  ``coordinates="relative"``: the OpenSim model's
    tree instead — pin angles along the chain crank 0, coupler 1, crank 1, coupler 2, … and
    the closures at the cranks' ground pivots A_1..A_N; there the horizontal position makes
    closure rows *dependent* (not vanishing), and every expression involves the whole chain
    before it (about N² terms: for small N)."""
    if N < 1:
        raise ValueError(f"N-four-bar: N = {N}; at least one window")
    if via == "mechanics":
        return _model_mechanics(N, name, partition)
    if coordinates == "relative":
        return _model_relative(N, name, partition)
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols
    from .iftomm_common import Body, rigid_bodies_QP

    qn, un = names(N)
    q, u = plain_symbols(qn), plain_symbols(un)
    th, ph = q[: N + 1], q[N + 1 :]
    L, m, g = sp.symbols("L m g", positive=True)
    inertia = sp.diag(0, 0, m * L**2 / 12)
    tip = [(k * L + L * sp.cos(th[k]), L * sp.sin(th[k]), 0) for k in range(N + 1)]
    bodies = [
        Body(
            ((k * L + L / 2 * sp.cos(th[k])), L / 2 * sp.sin(th[k]), 0),
            m,
            omega=(0, 0, u[k]),
            inertia=inertia,
            force=(0, -m * g, 0),
            name=f"crank{k}",
        )
        for k in range(N + 1)
    ]
    closures = {}
    for k in range(1, N + 1):
        a = ph[k - 1]
        bodies.append(
            Body(
                (tip[k - 1][0] + L / 2 * sp.cos(a), tip[k - 1][1] + L / 2 * sp.sin(a), 0),
                m,
                omega=(0, 0, u[N + k]),
                inertia=inertia,
                force=(0, -m * g, 0),
                name=f"coupler{k}",
            )
        )
        closures[f"close{k}_x"] = tip[k - 1][0] + L * sp.cos(a) - tip[k][0]
        closures[f"close{k}_y"] = tip[k - 1][1] + L * sp.sin(a) - tip[k][1]
    Q, P, T = rigid_bodies_QP(bodies, q, u)
    V = sum(m * g * b.r[1] for b in bodies)
    n = len(q)
    return MechanicalModel(
        name=name,
        q=q,
        u=u,
        params=(L, m, g),
        C=sp.eye(n),
        D=sp.zeros(n, 1),
        Q=Q,
        P=P,
        holonomic=closures,
        u_independent=(u[0],) if partition else (),
        q_dependent=tuple(q[1:]) if partition else (),
        singular_positions=True,
        energy=T + V,
        outputs=_outputs(th[0], u[0], L),
        description=f"{N} parallelogram windows: {2 * N + 1} rods, {2 * N} loop-closure equations",
    )


def _model_relative(N: int, name: str, partition: bool):
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols
    from .iftomm_common import Body, rigid_bodies_QP

    n = 2 * N + 1
    q = plain_symbols([f"r{k}" for k in range(n)])
    u = plain_symbols([f"dr{k}" for k in range(n)])
    L, m, g = sp.symbols("L m g", positive=True)
    inertia = sp.diag(0, 0, m * L**2 / 12)
    bodies, closures = [], {}
    x, y = sp.S.Zero, sp.S.Zero  # where the next rod is pinned (A_0 first, then the tips B_k)
    angle, rate = sp.S.Zero, sp.S.Zero
    for k in range(n):
        angle, rate = angle + q[k], rate + u[k]
        c, s_ = sp.cos(angle), sp.sin(angle)
        bodies.append(
            Body((x + L / 2 * c, y + L / 2 * s_, 0), m, omega=(0, 0, rate), inertia=inertia, force=(0, -m * g, 0))
        )
        if k % 2 == 1 or k == 0:  # crank 0 and the couplers: the next rod is pinned at their end
            x, y = x + L * c, y + L * s_
        else:  # crank k/2 hangs from the tip B_{k/2} to its ground pivot, and the next coupler
            closures[f"pivot{k // 2}_x"] = x + L * c - (k // 2) * L  # is pinned at that tip
            closures[f"pivot{k // 2}_y"] = y + L * s_
    Q, P, T = rigid_bodies_QP(bodies, q, u)
    V = sum(m * g * b.r[1] for b in bodies)
    return MechanicalModel(
        name=name,
        q=q,
        u=u,
        params=(L, m, g),
        C=sp.eye(n),
        D=sp.zeros(n, 1),
        Q=Q,
        P=P,
        holonomic=closures,
        u_independent=(u[0],) if partition else (),
        q_dependent=tuple(q[1:]) if partition else (),
        singular_positions=True,
        energy=T + V,
        outputs=_outputs(q[0], u[0], L),
        description=f"{N} windows in the OpenSim tree's relative pin angles",
    )


def relative_state(N: int = 2, theta0: float = math.pi / 2, vx_B0: float = 1.0, L: float = 1.0) -> dict[str, float]:
    """:func:`initial_state` in the relative coordinates of ``coordinates="relative"``: crank
    0 at θ0, each coupler horizontal, each further crank pointing from its tip to its pivot
    (absolute angle θ0 + π), every crank turning at the same rate."""
    w = -vx_B0 / (L * math.sin(theta0))
    state = {}
    absolute = [theta0 if k == 0 else (0.0 if k % 2 else theta0 + math.pi) for k in range(2 * N + 1)]
    rates = [w if k % 2 == 0 else 0.0 for k in range(2 * N + 1)]
    prev_a, prev_w = 0.0, 0.0
    for k in range(2 * N + 1):
        state[f"r{k}"], state[f"dr{k}"] = absolute[k] - prev_a, rates[k] - prev_w
        prev_a, prev_w = absolute[k], rates[k]
    return state


def _outputs(th0, w0, L):
    import sympy as sp

    return {
        "xB0": L * sp.cos(th0),
        "yB0": L * sp.sin(th0),
        "vxB0": -L * sp.sin(th0) * w0,
        "vyB0": L * sp.cos(th0) * w0,
    }


def _model_mechanics(N: int, name: str, partition: bool):
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..symbolic.model import MechanicalModel

    qn, un = names(N)
    q = list(me.dynamicsymbols(" ".join(qn), seq=True))
    u = list(me.dynamicsymbols(" ".join(un), seq=True))
    th, ph = q[: N + 1], q[N + 1 :]
    dth, dph = u[: N + 1], u[N + 1 :]
    L, m, g = sp.symbols("L m g", positive=True)
    Nf = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(Nf, 0)

    def e(a):
        return sp.cos(a) * Nf.x + sp.sin(a) * Nf.y

    bodies, loads, tips = [], [], []
    inertia = m * L**2 / 12
    for k in range(N + 1):  # cranks on ground pivots A_k
        A = O.locatenew(f"A{k}", k * L * Nf.x)
        A.set_vel(Nf, 0)
        F = Nf.orientnew(f"C{k}", "Axis", (th[k], Nf.z))
        F.set_ang_vel(Nf, dth[k] * Nf.z)
        G = A.locatenew(f"Gc{k}", L / 2 * e(th[k]))
        G.v2pt_theory(A, Nf, F)
        B = A.locatenew(f"B{k}", L * e(th[k]))
        B.v2pt_theory(A, Nf, F)
        tips.append(B)
        bodies.append(me.RigidBody(f"crank{k}", G, F, m, (me.inertia(F, 0, 0, inertia), G)))
        loads.append((G, -m * g * Nf.y))
    closures = {}
    for k in range(1, N + 1):  # couplers pinned at the tip of crank k-1
        F = Nf.orientnew(f"K{k}", "Axis", (ph[k - 1], Nf.z))
        F.set_ang_vel(Nf, dph[k - 1] * Nf.z)
        G = tips[k - 1].locatenew(f"Gk{k}", L / 2 * e(ph[k - 1]))
        G.v2pt_theory(tips[k - 1], Nf, F)
        bodies.append(me.RigidBody(f"coupler{k}", G, F, m, (me.inertia(F, 0, 0, inertia), G)))
        loads.append((G, -m * g * Nf.y))
        gap = (tips[k - 1].pos_from(O) + L * e(ph[k - 1]) - tips[k].pos_from(O)).to_matrix(Nf)
        closures[f"close{k}_x"] = sp.expand(gap[0])
        closures[f"close{k}_y"] = sp.expand(gap[1])
    energy = sum(b.kinetic_energy(Nf) for b in bodies) + sum(m * g * ld[0].pos_from(O).dot(Nf.y) for ld in loads)
    t = me.dynamicsymbols._t
    return MechanicalModel.from_mechanics(
        name,
        q=q,
        u=u,
        kd_eqs=[qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)],
        bodies=bodies,
        loads=loads,
        frame=Nf,
        params=(L, m, g),
        holonomic=closures,
        u_independent=(dth[0],) if partition else (),
        q_dependent=tuple(q[1:]) if partition else (),
        singular_positions=True,
        energy=energy,
        outputs=_outputs(th[0], dth[0], L),
        description=f"{N} parallelogram windows: {2 * N + 1} rods, {2 * N} loop-closure equations",
    )


def initial_state(N: int = 2, theta0: float = math.pi / 2, vx_B0: float = 1.0, L: float = 1.0) -> dict[str, float]:
    """A state on the parallelogram branch: every crank at ``theta0``, couplers horizontal, B0
    moving at ``vx_B0`` along x (the benchmark: θ0 = π/2, ẋ_B0 = 1 m/s)."""
    if abs(math.sin(theta0)) < 1e-12:
        raise ValueError("theta0 is a horizontal (singular) position: ẋ_B0 does not fix the crank speed there")
    w = -vx_B0 / (L * math.sin(theta0))
    qn, un = names(N)
    state = {}
    for k in range(N + 1):
        state[qn[k]], state[un[k]] = theta0, w
    for k in range(N + 1, 2 * N + 1):
        state[qn[k]], state[un[k]] = 0.0, 0.0
    return state


def pendulum_constants(N: int, L: float = 1.0, m: float = 1.0, g: float = 9.81) -> tuple[float, float]:
    """(I, K) of the exact motion I θ̈ = −K cos θ on the parallelogram branch."""
    return (N + 1) * m * L**2 / 3 + N * m * L**2, (N + 1) * m * g * L / 2 + N * m * g * L


def exact_motion(t, N: int = 2, theta0: float = math.pi / 2, omega0: float = -1.0, L=1.0, m=1.0, g=9.81):
    """θ(t), θ̇(t) of the parallelogram motion (every crank alike), to ~1e-13 (DOP853)."""
    import numpy as np
    from scipy.integrate import solve_ivp

    inertia, K = pendulum_constants(N, L, m, g)
    t = np.asarray(t, float)
    sol = solve_ivp(
        lambda _t, y: [y[1], -K / inertia * math.cos(y[0])],
        (0.0, float(t[-1])),
        [theta0, omega0],
        method="DOP853",
        rtol=1e-13,
        atol=1e-13,
        t_eval=t,
    )
    return sol.y[0], sol.y[1]


def acceptance(t, x, N: int = 2, L=1.0, m=1.0, g=9.81, energy=None) -> dict[str, float]:
    """The benchmark's quantity: B0's position and velocity against the exact motion (max
    errors over the run, m and m/s) and, given the energy history, its largest drift."""
    import numpy as np

    x = np.asarray(x, float)
    n = 2 * N + 1
    th0, w0 = x[0, 0], x[0, n]
    th, w = exact_motion(t, N, th0, w0, L, m, g)
    pos = max(np.abs(L * np.cos(x[:, 0]) - L * np.cos(th)).max(), np.abs(L * np.sin(x[:, 0]) - L * np.sin(th)).max())
    vel = max(
        np.abs(-L * np.sin(x[:, 0]) * x[:, n] + L * np.sin(th) * w).max(),
        np.abs(L * np.cos(x[:, 0]) * x[:, n] - L * np.cos(th) * w).max(),
    )
    out = {"B0_position": float(pos), "B0_velocity": float(vel)}
    if energy is not None:
        energy = np.asarray(energy, float)
        out["energy_drift"] = float(np.abs(energy - energy[0]).max())
    return out


def _visuals(N: int):
    def build():
        import sympy as sp

        from ..declare.visuals import Visuals, segments, sphere, trace
        from ..symbolic.model import plain_symbols

        qn, _ = names(N)
        q = plain_symbols(qn)
        th, ph = q[: N + 1], q[N + 1 :]
        L = sp.Symbol("L", positive=True)
        tip = [(k * L + L * sp.cos(th[k]), 0, L * sp.sin(th[k])) for k in range(N + 1)]
        cranks = [((k * L, 0, 0), tip[k]) for k in range(N + 1)]
        couplers = [
            (tip[k - 1], (tip[k - 1][0] + L * sp.cos(ph[k - 1]), 0, tip[k - 1][2] + L * sp.sin(ph[k - 1])))
            for k in range(1, N + 1)
        ]
        return Visuals(
            shapes=(
                segments("ground_line", [((-0.3 * L, 0, 0), ((N + 0.3) * L, 0, 0))], color=(80, 80, 80), thickness=2),
                segments("cranks", cranks, color=(40, 90, 200), thickness=5),
                segments("couplers", couplers, color=(200, 110, 40), thickness=5),
                sphere("B0", 0.05 * L, at=tip[0], color=(214, 48, 39)),
                trace("B0_path", tip[0]),
            ),
            view=(0.0, -1.0, 0.2),
        )

    return build


def iftomm_a02(N: int = 2) -> System:
    """The catalogue entry ``iftomm-a02`` (N = 2: the case OpenSim 3.2 times, 10 s); another N is
    the system ``iftomm-a02-n{N}`` — the benchmark's own N = 40 through a systems file
    (examples/iftomm_a02_n40.py: it derives a model of its own, so it is not built in)."""

    def variant():
        return model(N)

    return System(
        name="iftomm-a02" if N == 2 else f"iftomm-a02-n{N}",
        title=f"IFToMM A02: N-four-bar mechanism (N = {N})",
        variants=variant,
        parameters=PARAMETERS,
        default_initial=initial_state(N),
        initial_controls=INITIAL_CONTROLS,
        # N = 2: the case OpenSim times, at its Δt; a longer chain at the largest step that keeps the
        # benchmark's precision with a wide margin (N = 40, 20 s, Δt = 0.01: B0 within 1.8e-6 m and
        # 1.2e-5 m/s of the exact motion, 1e-3 allowed; 0.6 s of CPU against 3–5 s at Δt = 1e-3)
        default_dt=1e-3 if N == 2 else 1e-2,
        default_t_final=10.0,
        default_integrator="kutta-merson",
        default_gamma1=-20.0,
        default_gamma2=-100.0,
        default_projection="yoon",
        description=(
            "IFToMM benchmark A02: 2N+1 rods of 1 m and 1 kg in N parallelogram windows under gravity; "
            "the constraint Jacobian loses rank at the horizontal position."
        ),
        visuals=_visuals(N),
        what_to_try=WHAT_TO_TRY,
    )
