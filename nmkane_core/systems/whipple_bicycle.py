"""The Carvallo–Whipple bicycle in the benchmark parameters of Meijaard et al. (2007).

Four rigid bodies — rear wheel R, rear frame B with the rider, front frame H (fork and
handlebar), front wheel F — two knife-edge wheels rolling without slip on level ground.
Coordinates as in Moore (2012) (z down, x forward, y to the right):

* q1, q2  rear contact point in the ground plane (N.x, N.y); q3 yaw (about N.z);
* q4 roll (about the yaw frame's x); q5 pitch of the rear frame (about the roll frame's y;
  q5 = λ when upright); q6 rear wheel rotation; q7 steer (about the steer axis);
  q8 front wheel rotation;  u_i = dq_i/dt.

Constraints (Bajodah, Hodges & Chen's setting): four nonholonomic ones — the wheels' material
contact points have no horizontal velocity (``rear_longitudinal``, ``rear_lateral``,
``front_longitudinal``, ``front_lateral``) — and a holonomic one, the front wheel touching the
ground (``front_contact``, a function of q4, q5, q7; pitch q5 is its dependent coordinate).
Independent speeds u4 (roll rate), u6 (rear wheel rate), u7 (steer rate).  Forward speed
v = −rR·u6 when upright.

The holonomic equations Q u̇ = P come from sympy.physics.mechanics' KanesMethod on the
unconstrained system (eight speeds), exactly as for the paper's examples.  The geometry is
written directly in the benchmark parameters (Meijaard Table 1): the rear frame C is the
benchmark frame turned by λ about y, so that C.z is the steer axis; d1, d2, d3 (Moore's
offsets) and the mass centres l1..l4 follow from w, c, λ, rR, rF, xB, zB, xH, zH.

The system declares its stability sweep (``stability=``): upright straight running at a
forward speed, linearized in roll, steer and their rates —
`nmkane_core.analysis.eigensweep.state_at` gives that state and
`nmkane_core.analysis.eigensweep.sweep` the eigenvalues against speed (Meijaard et al.
(2007) Fig. 3).
"""

from __future__ import annotations

import math

from ..declare.stability import Stability
from ..declare.system import Parameter, System

NAME = "whipple-bicycle"
LAM = math.pi / 10

PARAMETERS = {
    "w": Parameter(1.02, 0.0, 10.0, "m", "wheel base"),
    "c": Parameter(0.08, -2.0, 2.0, "m", "trail"),
    "lam": Parameter(LAM, -1.5, 1.5, "rad", "steer axis tilt (from vertical)"),
    "g": Parameter(9.81, 0.0, 100.0, "m/s²", "gravitational acceleration", min_inclusive=True),
    "rR": Parameter(0.3, 0.0, 5.0, "m", "rear wheel radius"),
    "mR": Parameter(2.0, 0.0, 1e3, "kg", "rear wheel mass"),
    "IRxx": Parameter(0.0603, 0.0, 1e3, "kg·m²", "rear wheel moment of inertia about a diameter"),
    "IRyy": Parameter(0.12, 0.0, 1e3, "kg·m²", "rear wheel moment of inertia about the axle"),
    "xB": Parameter(0.3, -10.0, 10.0, "m", "rear frame (with rider) mass centre, forward of the rear contact"),
    "zB": Parameter(-0.9, -10.0, 10.0, "m", "rear frame (with rider) mass centre, z down (negative: above)"),
    "mB": Parameter(85.0, 0.0, 1e4, "kg", "rear frame (with rider) mass"),
    "IBxx": Parameter(9.2, 0.0, 1e4, "kg·m²", "rear frame inertia xx (benchmark axes)"),
    "IByy": Parameter(11.0, 0.0, 1e4, "kg·m²", "rear frame inertia yy"),
    "IBzz": Parameter(2.8, 0.0, 1e4, "kg·m²", "rear frame inertia zz"),
    "IBxz": Parameter(2.4, -1e4, 1e4, "kg·m²", "rear frame inertia xz (tensor element)"),
    "xH": Parameter(0.9, -10.0, 10.0, "m", "front frame mass centre, forward of the rear contact"),
    "zH": Parameter(-0.7, -10.0, 10.0, "m", "front frame mass centre, z down (negative: above)"),
    "mH": Parameter(4.0, 0.0, 1e4, "kg", "front frame (fork and handlebar) mass"),
    "IHxx": Parameter(0.05892, 0.0, 1e3, "kg·m²", "front frame inertia xx (benchmark axes)"),
    "IHyy": Parameter(0.06, 0.0, 1e3, "kg·m²", "front frame inertia yy"),
    "IHzz": Parameter(0.00708, 0.0, 1e3, "kg·m²", "front frame inertia zz"),
    "IHxz": Parameter(-0.00756, -1e3, 1e3, "kg·m²", "front frame inertia xz (tensor element)"),
    "rF": Parameter(0.35, 0.0, 5.0, "m", "front wheel radius"),
    "mF": Parameter(3.0, 0.0, 1e3, "kg", "front wheel mass"),
    "IFxx": Parameter(0.1405, 0.0, 1e3, "kg·m²", "front wheel moment of inertia about a diameter"),
    "IFyy": Parameter(0.28, 0.0, 1e3, "kg·m²", "front wheel moment of inertia about the axle"),
}
PARAM_NAMES = tuple(PARAMETERS)

#: upright straight running at 5 m/s, a full consistent state for the benchmark parameters:
#: upright and unsteered the steer axis is at λ from vertical, so the pitch q5 = λ for any
#: geometry; u1 = v, u6 = −v/rR, u8 = −v/rF (other parameters: completed from u6)
DEFAULT_SPEED = 5.0
DEFAULT_INITIAL = {
    "q1": 0.0,
    "q2": 0.0,
    "q3": 0.0,
    "q4": 0.0,
    "q5": LAM,
    "q6": 0.0,
    "q7": 0.0,
    "q8": 0.0,
    "u1": DEFAULT_SPEED,
    "u2": 0.0,
    "u3": 0.0,
    "u4": 0.0,
    "u5": 0.0,
    "u6": -DEFAULT_SPEED / 0.3,
    "u7": 0.0,
    "u8": -DEFAULT_SPEED / 0.35,
}


def _geometry():
    """Symbols, frames and points of the bicycle (sympy.physics.mechanics), shared by the
    model, the visuals and the events: (q, u, par, frames, points), ``par`` the parameters
    in `PARAM_NAMES` order, ``frames``/``points`` dicts by the names used below."""
    import sympy as sp
    from sympy.physics import mechanics as me

    q = me.dynamicsymbols("q1:9")
    u = me.dynamicsymbols("u1:9")
    par = sp.symbols(" ".join(PARAM_NAMES), real=True)
    P = dict(zip(PARAM_NAMES, par, strict=True))
    w, c, lam, rR, rF = P["w"], P["c"], P["lam"], P["rR"], P["rF"]
    xB, zB, xH, zH = P["xB"], P["zB"], P["xH"], P["zH"]

    # Moore's offsets in the benchmark parameters: d1 rear wheel centre → steer axis (along
    # C.x), d3 steer axis → front wheel centre (along E.x), d2 between their feet along the axis
    cl, sl = sp.cos(lam), sp.sin(lam)
    d1 = cl * (w + c) - rR * sl
    d3 = rF * sl - c * cl
    d2 = w * sl + (rR - rF) * cl
    # mass centres in the rear frame C (from the rear wheel centre) and the front frame E
    # (from the steer axis point), upright: benchmark (x, z) turned by λ
    l1, l2 = xB * cl - (zB + rR) * sl, xB * sl + (zB + rR) * cl
    l3, l4 = xH * cl - (zH + rR) * sl - d1, xH * sl + (zH + rR) * cl

    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (q[2], N.z))  # yaw
    B = A.orientnew("B", "Axis", (q[3], A.x))  # roll
    C = B.orientnew("C", "Axis", (q[4], B.y))  # pitch: rear frame, C.z along the steer axis
    D = C.orientnew("D", "Axis", (q[5], C.y))  # rear wheel
    E = C.orientnew("E", "Axis", (q[6], C.z))  # steer: front frame
    F = E.orientnew("F", "Axis", (q[7], E.y))  # front wheel
    Cb = C.orientnew("Cb", "Axis", (-lam, C.y))  # benchmark axes of the rear frame
    Eb = E.orientnew("Eb", "Axis", (-lam, E.y))  # benchmark axes of the front frame

    O = me.Point("O")
    dn = O.locatenew("dn", q[0] * N.x + q[1] * N.y)  # rear contact point
    do = dn.locatenew("do", -rR * B.z)  # rear wheel centre
    ce = do.locatenew("ce", d1 * C.x)  # on the steer axis
    bo = do.locatenew("bo", l1 * C.x + l2 * C.z)  # rear frame mass centre
    fo = ce.locatenew("fo", d2 * C.z + d3 * E.x)  # front wheel centre
    ho = ce.locatenew("ho", l3 * E.x + l4 * E.z)  # front frame mass centre
    # contact geometry: s = E.y·A.z; the front contact lies rF from the centre along the
    # wheel plane's steepest descent (A.z − s E.y)/√(1 − s²)
    s = E.y.dot(A.z)
    root = sp.sqrt(1 - s**2)
    fn = fo.locatenew("fn", rF * (A.z - s * E.y) / root)  # front contact point
    frames = dict(N=N, A=A, B=B, C=C, D=D, E=E, F=F, Cb=Cb, Eb=Eb)
    points = dict(O=O, dn=dn, do=do, ce=ce, bo=bo, fo=fo, ho=ho, fn=fn)
    return q, u, par, frames, points, (d1, d2, d3, root)


def _mechanics():
    """Bodies, loads and constraints (sympy.physics.mechanics), as a dict, for `_model`
    and for the sympy-route benchmark (`nmkane_core.bench.rows`)."""
    from sympy.physics import mechanics as me

    q, u, par, fr, pt, (_, _, _, root) = _geometry()
    t = me.dynamicsymbols._t
    P = dict(zip(PARAM_NAMES, par, strict=True))
    g, rR, rF = P["g"], P["rR"], P["rF"]
    mR, mB, mH, mF = P["mR"], P["mB"], P["mH"], P["mF"]
    N, A, B, C, D, E, F, Cb, Eb = (fr[k] for k in ("N", "A", "B", "C", "D", "E", "F", "Cb", "Eb"))
    O, dn, do, ce, bo, fo, ho = (pt[k] for k in ("O", "dn", "do", "ce", "bo", "fo", "ho"))
    A.set_ang_vel(N, u[2] * N.z)
    B.set_ang_vel(A, u[3] * A.x)
    C.set_ang_vel(B, u[4] * B.y)
    D.set_ang_vel(C, u[5] * C.y)
    E.set_ang_vel(C, u[6] * C.z)
    F.set_ang_vel(E, u[7] * E.y)
    O.set_vel(N, 0)
    dn.set_vel(N, u[0] * N.x + u[1] * N.y)
    do.v2pt_theory(dn, N, B)
    ce.v2pt_theory(do, N, C)
    bo.v2pt_theory(do, N, C)
    fo.v2pt_theory(ce, N, E)
    ho.v2pt_theory(ce, N, E)
    IRxx, IRyy, IFxx, IFyy = P["IRxx"], P["IRyy"], P["IFxx"], P["IFyy"]
    IBxx, IByy, IBzz, IBxz = P["IBxx"], P["IByy"], P["IBzz"], P["IBxz"]
    IHxx, IHyy, IHzz, IHxz = P["IHxx"], P["IHyy"], P["IHzz"], P["IHxz"]
    s = E.y.dot(A.z)

    rear = me.RigidBody("R", do, D, mR, (me.inertia(C, IRxx, IRyy, IRxx), do))
    frame = me.RigidBody("B", bo, C, mB, (me.inertia(Cb, IBxx, IByy, IBzz, 0, 0, IBxz), bo))
    fork = me.RigidBody("H", ho, E, mH, (me.inertia(Eb, IHxx, IHyy, IHzz, 0, 0, IHxz), ho))
    front = me.RigidBody("F", fo, F, mF, (me.inertia(E, IFxx, IFyy, IFxx), fo))
    bodies = [rear, frame, fork, front]
    loads = [(p, m * g * N.z) for p, m in ((do, mR), (bo, mB), (ho, mH), (fo, mF))]

    to_front_contact = rF * (A.z - s * E.y) / root
    v_rear = do.vel(N) + D.ang_vel_in(N).cross(rR * B.z)  # material contact points
    v_front = fo.vel(N) + F.ang_vel_in(N).cross(to_front_contact)
    nonholonomic = {
        "rear_longitudinal": v_rear.dot(A.x),
        "rear_lateral": v_rear.dot(A.y),
        "front_longitudinal": v_front.dot(A.x),
        "front_lateral": v_front.dot(A.y),
    }
    # (fn − dn)·A.z = 0: the front contact point on the ground
    holonomic = {"front_contact": fo.pos_from(dn).dot(A.z) + rF * root}

    kinetic = sum(b.kinetic_energy(N) for b in bodies)
    potential = -g * sum(m * p.pos_from(dn).dot(N.z) for p, m in ((do, mR), (bo, mB), (ho, mH), (fo, mF)))
    kd = [qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)]
    return dict(
        q=q,
        u=u,
        par=par,
        N=N,
        kd=kd,
        bodies=bodies,
        loads=loads,
        nonholonomic=nonholonomic,
        holonomic=holonomic,
        energy=kinetic + potential,
    )


def _model():
    from ..symbolic.model import MechanicalModel

    m = _mechanics()
    q, u, par, N, kd, bodies, loads = (m[k] for k in ("q", "u", "par", "N", "kd", "bodies", "loads"))
    nonholonomic, holonomic = m["nonholonomic"], m["holonomic"]
    return MechanicalModel.from_mechanics(
        "default",
        q=q,
        u=u,
        kd_eqs=kd,
        bodies=bodies,
        loads=loads,
        frame=N,
        params=par,
        nonholonomic=nonholonomic,
        holonomic=holonomic,
        u_independent=(u[3], u[5], u[6]),
        q_dependent=(q[4],),
        energy=m["energy"],
        description="Carvallo–Whipple bicycle, Moore's coordinates, Meijaard's benchmark parameters",
    )


#: drawn geometry (not in the benchmark): the head tube's top and bottom heights, the
#: handlebar's half width (its grips are what touches the ground first in a fall)
HEAD_TOP, HEAD_BOTTOM, BAR_HALF_WIDTH = 1.0, 0.65, 0.3


def _drawn():
    """World points (z up: Moore's N turned by π about x) of the drawing and the event."""
    import sympy as sp

    q, _, par, fr, pt, (d1, _, _, _) = _geometry()
    P = dict(zip(PARAM_NAMES, par, strict=True))
    w, c, lam, rR = P["w"], P["c"], P["lam"], P["rR"]
    N, Cb, Eb = fr["N"], fr["Cb"], fr["Eb"]
    cl, sl = sp.cos(lam), sp.sin(lam)
    flip = sp.diag(1, -1, -1)

    def world(point):
        return tuple(flip * point.pos_from(pt["O"]).to_matrix(N))

    def rear(x, z):  # a rear-frame point at benchmark (x, z) (upright: from the rear contact, z down)
        return pt["do"].locatenew("r", x * Cb.x + (z + rR) * Cb.z)

    def front(x, z):  # a front-frame point at benchmark (x, z) (upright, unsteered)
        xc, zc = d1 * cl, -rR - d1 * sl  # the steer axis point ce in benchmark coordinates
        return pt["ce"].locatenew("f", (x - xc) * Eb.x + (z - zc) * Eb.z)

    def on_axis(height):  # the steer axis at a height (upright): it meets the ground at x = w + c
        return (w + c - height * sl / cl, -height)

    head_top, head_bottom = front(*on_axis(HEAD_TOP)), front(*on_axis(HEAD_BOTTOM))
    bar = pt["ce"].locatenew("bar", head_top.pos_from(pt["ce"]) - 0.12 * Eb.x)
    grips = [bar.locatenew(f"g{k}", k * BAR_HALF_WIDTH * Eb.y) for k in (-1, 1)]
    seat, crank = rear(0.25, -0.85), rear(0.45, -0.3)
    shoulder = rear(0.42, -1.45)
    return {
        "world": world,
        "flip": flip,
        "q": q,
        "par": P,
        "frames": fr,
        "points": pt,
        "lines": {
            "rear_frame": [(pt["do"], crank), (crank, seat), (seat, pt["do"]), (seat, head_top), (crank, head_bottom)],
            "fork": [(head_top, pt["fo"]), (head_top, bar), (grips[0], grips[1])],
            "rider": [(shoulder, grips[0]), (shoulder, grips[1]), (seat, crank)],
        },
        "grips": grips,
    }


def _visuals():
    from ..declare.visuals import Frame, Visuals, box, cylinder, ground, segments, sphere, trace

    d = _drawn()
    world, flip, fr, pt, P = d["world"], d["flip"], d["frames"], d["points"], d["par"]
    N = fr["N"]
    rR, rF = P["rR"], P["rF"]

    def frame(name, point, body):
        return Frame(name, world(pt[point]), flip * N.dcm(fr[body]))

    wheel, spoke, frame_col = (40, 40, 45), (230, 200, 60), (200, 40, 40)
    shapes = [ground(0)]
    for name, r in (("rear_wheel", rR), ("front_wheel", rF)):
        shapes += [
            cylinder(name, name, r, 0.04, axis="y", color=wheel),
            cylinder(f"{name}_hub", name, 0.05, 0.08, axis="y", color=(160, 160, 170)),
            box(f"{name}_spoke", name, (1.9 * r, 0.05, 0.04), color=spoke),  # the rotation made visible
            box(f"{name}_spoke2", name, (0.04, 0.05, 1.9 * r), color=(90, 90, 100)),
        ]
    for group, color in (("rear_frame", frame_col), ("fork", (60, 60, 70)), ("rider", (40, 90, 160))):
        shapes.append(segments(group, [(world(a), world(b)) for a, b in d["lines"][group]], color=color))
    shapes += [
        box("torso", "rear", (0.22, 0.36, 0.6), offset=(0.36, 0, -1.15 + rR), color=(40, 90, 160)),
        box("head_tube", "front", (0.05, 0.05, HEAD_TOP - HEAD_BOTTOM), offset=(0, 0, 0), color=(60, 60, 70)),
        sphere("head", 0.11, frame="rear", offset=(0.48, 0, -1.58 + rR), color=(230, 190, 150)),
        sphere("rear_mass_centre", 0.04, at=world(pt["bo"]), color=(20, 20, 20)),
        trace("rear_contact", (*world(pt["dn"])[:2], 0.002), color=(214, 48, 39)),
        trace("front_contact", (*world(pt["fn"])[:2], 0.002), color=(40, 110, 214)),
    ]
    frames = (
        frame("rear", "do", "Cb"),
        Frame(
            "front", tuple((a + b) / 2 for a, b in zip(*map(world, _head_ends(d)), strict=True)), flip * N.dcm(fr["E"])
        ),
        frame("rear_wheel", "do", "D"),
        frame("front_wheel", "fo", "F"),
    )
    return Visuals(frames=frames, shapes=tuple(shapes))


def _head_ends(d):
    rf = d["lines"]["rear_frame"]
    return rf[3][1], rf[4][1]  # head tube top, bottom (the ends of the top and down tubes)


def _events():
    """The grips of the handlebar reaching the ground: the bicycle has fallen."""
    import sympy as sp

    d = _drawn()
    heights = [d["world"](g)[2] for g in d["grips"]]
    return {"handlebar_touches_ground": -sp.Min(*heights)}


def _forces(variant: str):
    """The ground's force on each tyre at its contact point, in the yaw frame A of the
    constraints (x forward, y to the right in Moore's axes; components: longitudinal, lateral,
    normal = up).

    Rear and front friction by the multiplier route: the rolling constraints are written on the
    material contact points' velocities (v · A.x, v · A.y), so the horizontal forces are
    λ_longitudinal A.x + λ_lateral A.y.  The front normal force too: the holonomic contact
    constraint's rate is ψ̇ = v_F · A.z (the geometric contact point moves along the rim's
    horizontal tangent), so the front wheel gets λ_front_contact A.z — its upward component is
    −λ_front_contact.  The rear normal force is non-contributing (the rear wheel's height is built
    into the coordinates), so it comes from Newton's law on the whole bicycle, vertically:
    N_R = g Σm + Σ m_i z̈_i − N_F (z up), the z̈_i of the four mass centres from q, u and u̇."""
    import sympy as sp
    from sympy.physics import mechanics as me

    from ..declare.forces import Forces, PointForce, multiplier

    d = _drawn()
    world, flip, fr, pt, P, q = d["world"], d["flip"], d["frames"], d["points"], d["par"], d["q"]
    N, A = fr["N"], fr["A"]
    t = me.dynamicsymbols._t
    u = me.dynamicsymbols("u1:9")
    qd = {qi.diff(t): ui for qi, ui in zip(q, u, strict=True)}
    g = P["g"]
    masses = ((pt["do"], P["mR"]), (pt["bo"], P["mB"]), (pt["ho"], P["mH"]), (pt["fo"], P["mF"]))
    # heights (z up) of the mass centres above the ground; their second derivatives in q, u, u̇
    zdd = [(-p.pos_from(pt["dn"]).dot(N.z)).diff(t).xreplace(qd).diff(t).xreplace(qd) for p, _ in masses]
    total = sum(m for _, m in masses)
    front_up = -multiplier("front_contact")
    rear_up = g * total + sum(m * a for (_, m), a in zip(masses, zdd, strict=True)) - front_up
    axes = sp.Matrix.hstack(flip * A.x.to_matrix(N), flip * A.y.to_matrix(N), sp.Matrix([0, 0, 1]))

    def tyre(name, point, wheel, up, route):
        return PointForce(
            f"{name}_tyre",
            at=world(pt[point]),
            components=(multiplier(f"{name}_longitudinal"), multiplier(f"{name}_lateral"), up),
            frame=axes,
            labels=("longitudinal", "lateral", "normal"),
            route=route,
            on=f"the {wheel} wheel, at its contact point",
            description=f"the ground's force on the {wheel} tyre: friction along and across the heading (yaw "
            "frame), and the normal force (up)",
        )

    return Forces(
        forces=(
            tyre("rear", "dn", "rear", rear_up, "multipliers + newton"),
            tyre("front", "fn", "front", front_up, "multipliers"),
        ),
    )


def _stability_state(speed, params):
    return {"u6": -speed / params["rR"]}


def _speed_of(initial, params):
    return -float(initial.get("u6", 0.0)) * params["rR"]


#: the benchmark's weave and capsize speeds (Meijaard et al. 2007, Table 2)
WEAVE_SPEED, CAPSIZE_SPEED = 4.29238253634111, 6.02426201538837

#: the initial values offered as sliders (range, label)
INITIAL_CONTROLS = {
    "u6": (-40.0, 0.0, "u6 = q̇6 (rear wheel rate = −speed/rR; −16.7: 5 m/s) [rad/s]"),
    "q4": (-0.6, 0.6, "q4 (roll) [rad]"),
    "q7": (-0.6, 0.6, "q7 (steer) [rad]"),
    "u4": (-2.0, 2.0, "u4 = q̇4 (roll rate) [rad/s]"),
    "u7": (-2.0, 2.0, "u7 = q̇7 (steer rate) [rad/s]"),
    "q3": (-3.2, 3.2, "q3 (heading) [rad]"),
}

WHAT_TO_TRY = (
    "At 5 m/s (u6 = −16.7 rad/s) give it a roll rate u4 = 0.5 rad/s: the wobble dies out — the "
    "bicycle is self-stable between the weave speed 4.29 m/s and the capsize speed 6.02 m/s. At 3 m/s "
    "(u6 = −10) the same push makes it fall: the run stops with the event handlebar_touches_ground. "
    "Above 6 m/s (u6 = −25) it capsizes slowly. The eigenvalue plot shows why."
)


def whipple_bicycle() -> System:
    return System(
        name=NAME,
        title="Whipple bicycle (benchmark)",
        variants=_model,
        parameters=PARAMETERS,
        default_initial=DEFAULT_INITIAL,
        default_dt=0.001,
        default_t_final=5.0,
        default_integrator="kutta-merson",
        description="Carvallo–Whipple bicycle with the benchmark parameters of Meijaard et al. (2007): "
        "rolling without slip (nonholonomic), front wheel ground contact (holonomic).",
        visuals=_visuals,
        events=_events,
        forces=_forces,
        what_to_try=WHAT_TO_TRY,
        initial_controls=INITIAL_CONTROLS,
        stability=Stability(
            over="speed",
            unit="m/s",
            start=0.0,
            stop=10.0,
            count=101,
            state=_stability_state,
            keep=("q4", "q7", "u4", "u7"),
            value_of=_speed_of,
            names={"complex": "weave", "real": "capsize", "fast": "castor"},
            reference={"weave": WEAVE_SPEED, "capsize": CAPSIZE_SPEED},
        ),
    )
