"""IFToMM benchmark A03: Andrews' squeezing mechanism (seven bodies, a very small time scale).

Published specification: the OpenSim 3.2 implementation of the IFToMM / MBS benchmark
library's problem A03 (RehabEngGroup/MBSbenchmarksInOpenSim, help/benchmarks/
A03_AndrewsMechanism.rst): "Andrew's squeezer mechanism is a planar system composed of
seven bodies interconnected through revolution joints, and driven by a motor located in
O"; spring 4530 N/m of rest length 0.07785 m, motor torque 0.033 N·m, β0 = −0.0620 rad;
"The objective of the simulation is to measure the system total energy balance ...
ΔU = T + V − E0 − τ(β − β0) ... theoretical value for ΔU is zero"; 0.384 s of CPU.

Equations: the benchmark's origin, Schiehlen's squeezer as written by Hairer & Wanner
(Solving ODEs II, p. 377) and kept in the CWI / Bari test set for IVP solvers ("andrews",
https://archimede.uniba.it/~testset/problems/andrews.php; the same numbers in deTestSet's
``ex_andrews.R``): seven angles β, Θ, γ, Φ, δ, Ω, ε, their mass matrix M(q) and forces
f(q, q̇) (the spring between point D of body 3 and the ground point C, the motor torque on
β), six holonomic loop-closure equations g(q) = 0; initial angles (to 30 digits) and
speeds 0; the reference solution at t = 0.03 s (:data:`REFERENCE_003`, the test set's
``SOLN``).  Here: q̇ = u, Q = M, P = f, the six g's as the holonomic constraints, u_I = β̇.

The reported "energy" is the benchmark's balance T + V − τ β, so that its drift is ΔU.
"""

from __future__ import annotations

from ..declare.system import Parameter, System

#: OpenSim 3.2 CPU time (help/benchmarks/A03_AndrewsMechanism.rst: "required 0.384 seconds")
OPENSIM_CPU_S = 0.384

#: the parameters of the test set (deTestSet ex_andrews.R, Hairer & Wanner II, p. 377)
VALUES = {
    "m1": (0.04325, "kg", "mass of body 1 (OF)"),
    "m2": (0.00365, "kg", "mass of body 2 (FE)"),
    "m3": (0.02373, "kg", "mass of body 3 (the triangle BDE)"),
    "m4": (0.00706, "kg", "mass of body 4 (EG)"),
    "m5": (0.07050, "kg", "mass of body 5 (GA)"),
    "m6": (0.00706, "kg", "mass of body 6 (EH)"),
    "m7": (0.05498, "kg", "mass of body 7 (HA)"),
    "i1": (2.194e-6, "kg·m²", "inertia of body 1"),
    "i2": (4.410e-7, "kg·m²", "inertia of body 2"),
    "i3": (5.255e-6, "kg·m²", "inertia of body 3"),
    "i4": (5.667e-7, "kg·m²", "inertia of body 4"),
    "i5": (1.169e-5, "kg·m²", "inertia of body 5"),
    "i6": (5.667e-7, "kg·m²", "inertia of body 6"),
    "i7": (1.912e-5, "kg·m²", "inertia of body 7"),
    "xa": (-0.06934, "m", "ground point A, x"),
    "ya": (-0.00227, "m", "ground point A, y"),
    "xb": (-0.03635, "m", "ground point B, x"),
    "yb": (0.03273, "m", "ground point B, y"),
    "xc": (0.014, "m", "spring anchor C, x"),
    "yc": (0.072, "m", "spring anchor C, y"),
    "c0": (4530.0, "N/m", "spring stiffness"),
    "l0": (0.07785, "m", "spring rest length"),
    "mom": (0.033, "N·m", "motor torque on β"),
    "d": (28e-3, "m", "geometry (test set's d)"),
    "da": (115e-4, "m", "geometry (da)"),
    "e": (2e-2, "m", "geometry (e)"),
    "ea": (1421e-5, "m", "geometry (ea)"),
    "rr": (7e-3, "m", "geometry (rr)"),
    "ra": (92e-5, "m", "geometry (ra)"),
    "ss": (35e-3, "m", "geometry (ss)"),
    "sa": (1874e-5, "m", "geometry (sa)"),
    "sb": (1043e-5, "m", "geometry (sb)"),
    "sc": (18e-3, "m", "geometry (sc)"),
    "sd": (2e-2, "m", "geometry (sd)"),
    "ta": (2308e-5, "m", "geometry (ta)"),
    "tb": (916e-5, "m", "geometry (tb)"),
    "u": (4e-2, "m", "geometry (u)"),
    "ua": (1228e-5, "m", "geometry (ua)"),
    "ub": (449e-5, "m", "geometry (ub)"),
    "zf": (2e-2, "m", "geometry (zf)"),
    "zt": (4e-2, "m", "geometry (zt)"),
    "fa": (1421e-5, "m", "geometry (fa)"),
}

PARAMETERS = {
    k: Parameter(v, *((0.0, 1e6) if v > 0 else (-1.0, 1.0)), unit, text, min_inclusive=(k == "mom"))
    for k, (v, unit, text) in VALUES.items()
}

NAMES = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")

#: initial angles (test set, to 30 digits); the speeds start at 0
INITIAL = (
    -0.0617138900142764496358948458001,
    0.0,
    0.455279819163070380255912382449,
    0.222668390165885884674473185609,
    0.487364979543842550225598953530,
    -0.222668390165885884674473185609,
    1.23054744454982119249735015568,
)

#: the test set's reference solution at t = 0.03 s (SOLN, angles in rad)
REFERENCE_003 = (
    0.1581077119629904e2,
    -0.1575637105984298e2,
    0.4082224013073101e-1,
    -0.5347301163226948,
    0.5244099658805304,
    0.5347301163226948,
    0.1048080741042263e1,
)

WHAT_TO_TRY = (
    "A 0.033 N·m motor drives a linkage of grams and centimetres: in 0.03 s the crank β turns "
    "two and a half times. The reported energy is the benchmark's balance T + V − τβ: its drift is "
    "ΔU, zero in theory, 2.5e-6 J at the page's step (dt = 1e-4). Try larger steps and watch ΔU grow "
    "(1e-3 J at dt = 5e-4; at dt = 2e-3 the run blows up); set mom = 0 and nothing moves: the spring is "
    "balanced at the start (nudge β by 0.01 rad and it alone turns the crank once round); soften the "
    "spring (c0 = 100) and the squeezing slows down."
)


def model(name: str = "default"):
    import sympy as sp

    from ..symbolic.model import MechanicalModel, plain_symbols

    q = plain_symbols(NAMES)
    u = plain_symbols(["d" + s for s in NAMES])
    P_ = {k: sp.Symbol(k, real=True) for k in VALUES}
    globals_ = P_
    be, Th, ga, Ph, de, Om, ep = q
    m1, m2, m3, m4, m5, m6, m7 = (globals_[f"m{i}"] for i in range(1, 8))
    i1, i2, i3, i4, i5, i6, i7 = (globals_[f"i{i}"] for i in range(1, 8))
    g = globals_
    d, da, e, ea, rr, ra = g["d"], g["da"], g["e"], g["ea"], g["rr"], g["ra"]
    ss, sa, sb, sc, sd = g["ss"], g["sa"], g["sb"], g["sc"], g["sd"]
    ta, tb, uu, ua, ub = g["ta"], g["tb"], g["u"], g["ua"], g["ub"]
    zf, zt, fa = g["zf"], g["zt"], g["fa"]
    xa, ya, xb, yb, xc, yc = g["xa"], g["ya"], g["xb"], g["yb"], g["xc"], g["yc"]
    c0, l0, mom = g["c0"], g["l0"], g["mom"]
    M = sp.zeros(7, 7)
    M[0, 0] = m1 * ra**2 + m2 * (rr**2 - 2 * da * rr * sp.cos(Th) + da**2) + i1 + i2
    M[1, 0] = M[0, 1] = m2 * (da**2 - da * rr * sp.cos(Th)) + i2
    M[1, 1] = m2 * da**2 + i2
    M[2, 2] = m3 * (sa**2 + sb**2) + i3
    M[3, 3] = m4 * (e - ea) ** 2 + i4
    M[4, 3] = M[3, 4] = m4 * ((e - ea) ** 2 + zt * (e - ea) * sp.sin(Ph)) + i4
    M[4, 4] = m4 * (zt**2 + 2 * zt * (e - ea) * sp.sin(Ph) + (e - ea) ** 2) + m5 * (ta**2 + tb**2) + i4 + i5
    M[5, 5] = m6 * (zf - fa) ** 2 + i6
    M[6, 5] = M[5, 6] = m6 * ((zf - fa) ** 2 - uu * (zf - fa) * sp.sin(Om)) + i6
    M[6, 6] = m6 * ((zf - fa) ** 2 - 2 * uu * (zf - fa) * sp.sin(Om) + uu**2) + m7 * (ua**2 + ub**2) + i6 + i7
    u1, u2, _, u4, u5, u6, u7 = u
    xd = sd * sp.cos(ga) + sc * sp.sin(ga) + xb
    yd = sd * sp.sin(ga) - sc * sp.cos(ga) + yb
    Ls = sp.sqrt((xd - xc) ** 2 + (yd - yc) ** 2)
    F = -c0 * (Ls - l0) / Ls
    f = sp.Matrix(
        [
            mom - m2 * da * rr * u2 * (u2 + 2 * u1) * sp.sin(Th),
            m2 * da * rr * u1**2 * sp.sin(Th),
            F * (xd - xc) * (sc * sp.cos(ga) - sd * sp.sin(ga)) + F * (yd - yc) * (sd * sp.cos(ga) + sc * sp.sin(ga)),
            m4 * zt * (e - ea) * u5**2 * sp.cos(Ph),
            -m4 * zt * (e - ea) * u4 * (u4 + 2 * u5) * sp.cos(Ph),
            -m6 * uu * (zf - fa) * u7**2 * sp.cos(Om),
            m6 * uu * (zf - fa) * u6 * (u6 + 2 * u7) * sp.cos(Om),
        ]
    )
    closures = {
        "g1": rr * sp.cos(be) - d * sp.cos(be + Th) - ss * sp.sin(ga) - xb,
        "g2": rr * sp.sin(be) - d * sp.sin(be + Th) + ss * sp.cos(ga) - yb,
        "g3": rr * sp.cos(be) - d * sp.cos(be + Th) - e * sp.sin(Ph + de) - zt * sp.cos(de) - xa,
        "g4": rr * sp.sin(be) - d * sp.sin(be + Th) + e * sp.cos(Ph + de) - zt * sp.sin(de) - ya,
        "g5": rr * sp.cos(be) - d * sp.cos(be + Th) - zf * sp.cos(Om + ep) - uu * sp.sin(ep) - xa,
        "g6": rr * sp.sin(be) - d * sp.sin(be + Th) - zf * sp.sin(Om + ep) + uu * sp.cos(ep) - ya,
    }
    uv = sp.Matrix(u)
    T = (uv.T * M * uv)[0] / 2
    V = c0 * (Ls - l0) ** 2 / 2
    return MechanicalModel(
        name=name,
        q=q,
        u=u,
        params=tuple(P_[k] for k in VALUES),
        C=sp.eye(7),
        D=sp.zeros(7, 1),
        Q=M,
        P=f,
        holonomic=closures,
        u_independent=(u[0],),
        q_dependent=q[1:],
        energy=T + V - mom * be,  # the benchmark's balance: its drift is ΔU
        outputs={"kinetic": T, "spring": V},
        description="Andrews' squeezer (Hairer & Wanner): 7 angles, 6 loop closures, spring and motor",
    )


def initial_state() -> dict[str, float]:
    state = dict(zip(NAMES, INITIAL, strict=True))
    state.update({"d" + n: 0.0 for n in NAMES})
    return state


def acceptance(t, energy, final_angles=None) -> dict[str, float]:
    """The benchmark's quantities: the energy balance ΔU = T + V − E0 − τ(β − β0) (the
    model's reported energy is T + V − τβ: its largest drift is max |ΔU|, J) and, given the
    seven angles at t = 0.03 s, their largest difference from the test set's solution."""
    import numpy as np

    energy = np.asarray(energy, float)
    out = {"energy_balance": float(np.abs(energy - energy[0]).max())}
    if final_angles is not None:
        out["angles_at_0.03"] = float(np.abs(np.asarray(final_angles, float) - np.array(REFERENCE_003)).max())
    return out


def _visuals():
    import sympy as sp

    from ..declare.visuals import Visuals, segments, sphere, trace
    from ..symbolic.model import plain_symbols

    be, Th, ga, _, de, _, ep = plain_symbols(NAMES)
    P = {k: sp.Symbol(k, real=True) for k in VALUES}
    rr, d, ss, e, zt, zf, uu = P["rr"], P["d"], P["ss"], P["e"], P["zt"], P["zf"], P["u"]
    xa, ya, xb, yb, xc, yc = P["xa"], P["ya"], P["xb"], P["yb"], P["xc"], P["yc"]
    sd, sc = P["sd"], P["sc"]

    def w(x, y):  # the mechanism's plane is the viewer's x–z plane
        return (x, 0, y)

    F = (rr * sp.cos(be), rr * sp.sin(be))
    E = (F[0] - d * sp.cos(be + Th), F[1] - d * sp.sin(be + Th))
    B = (xb, yb)
    A = (xa, ya)
    G = (A[0] + zt * sp.cos(de), A[1] + zt * sp.sin(de))
    H = (A[0] + uu * sp.sin(ep), A[1] - uu * sp.cos(ep))
    D = (sd * sp.cos(ga) + sc * sp.sin(ga) + xb, sd * sp.sin(ga) - sc * sp.cos(ga) + yb)
    del ss, e, zf
    return Visuals(
        shapes=(
            segments(
                "links",
                [(w(0, 0), w(*F)), (w(*F), w(*E)), (w(*E), w(*G)), (w(*G), w(*A)), (w(*E), w(*H)), (w(*H), w(*A))],
                color=(40, 90, 200),
                thickness=4,
            ),
            segments("triangle", [(w(*B), w(*D)), (w(*D), w(*E)), (w(*E), w(*B))], color=(200, 110, 40), thickness=4),
            segments("spring", [(w(*D), w(xc, yc))], color=(90, 160, 60), thickness=2),
            sphere("F", 0.002, at=w(*F), color=(214, 48, 39)),
            trace("F_path", w(*F)),
        ),
        view=(0.0, -1.0, 0.2),
    )


def iftomm_a03() -> System:
    return System(
        name="iftomm-a03",
        title="IFToMM A03: Andrews' squeezing mechanism",
        variants=model,
        parameters=PARAMETERS,
        default_initial=initial_state(),
        initial_controls={
            "beta": (-0.2, 0.1, "β [rad] (the driven crank's angle; the others follow from the loops)"),
            "dbeta": (-10.0, 10.0, "dbeta = β̇ (the driven crank's rate) [rad/s]"),
        },
        default_dt=1e-5,
        default_t_final=0.03,
        default_integrator="kutta-merson",
        default_gamma1=-2e3,
        default_gamma2=-1e6,
        description="IFToMM benchmark A03: seven bodies, six loop closures, a spring and a motor; 0.03 s.",
        visuals=_visuals,
        what_to_try=WHAT_TO_TRY,
        showcase={"speed": 0.02},
    )
