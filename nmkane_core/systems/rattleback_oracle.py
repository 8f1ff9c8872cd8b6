"""An independent reference for the rattleback: Kane's *minimal* equations from
sympy.physics.mechanics' KanesMethod, integrated by scipy (tests).

Written in Kane & Levinson's (1982) own terms, sharing nothing with the nonminimal
model (`nmkane_core.systems.rattleback`) or with `nmkane_core.declare.contact`: the inertia
as K&L give it — moments A, B, C about the geometric axes through the mass centre G and the
product D (the tensor's xy element) —, the body frame oriented by sympy's body-fixed ZXY
(yaw ψ, roll θ about the yawed x, pitch φ about the body's y), G's height written from the
ellipsoid's lowest point by hand, so that the body stays on the plane by construction
(no holonomic constraint: five coordinates ψ, θ, φ, x, y), the body rates ω1..ω3 as the
independent speeds and G's horizontal velocity (ẋ, ẏ) as the dependent ones, bound by the
no-slip constraints through KanesMethod's ``u_dependent`` and ``velocity_constraints``.
``rhs`` is lambdified ``mass_matrix_full`` and ``forcing_full`` and a numpy solve per call.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np

#: Kane & Levinson (1982) parameters, SI: ellipsoid semi-axes a, b, c; G a distance h below the
#: ellipsoid's centre; mass m; A, B, C, D the inertia about G in the geometric axes
KANE_LEVINSON = dict(a=0.20, b=0.03, c=0.02, h=0.01, m=1.0, A=2e-4, B=1.6e-3, C=1.7e-3, D=-2e-5, g=9.81)


@cache
def _kane():
    import sympy as sp
    from sympy.physics import mechanics as me

    psi, th, ph, x, y = q = me.dynamicsymbols("psi th ph x y")
    w1, w2, w3, vx, vy = u = me.dynamicsymbols("w1 w2 w3 vx vy")
    a, b, c, h, m, A, B, C, D, g = sp.symbols("a b c h m A B C D g")
    N = me.ReferenceFrame("N")
    R = N.orientnew("R", "Body", (psi, th, ph), "ZXY")
    w_of_qdot = R.ang_vel_in(N)
    R.set_ang_vel(N, w1 * R.x + w2 * R.y + w3 * R.z)
    kd = [(w_of_qdot - R.ang_vel_in(N)).dot(e) for e in (R.x, R.y, R.z)] + [x.diff() - vx, y.diff() - vy]
    t = me.dynamicsymbols._t
    qdot = sp.solve(kd, [qi.diff(t) for qi in q], dict=True)[0]
    mu = [N.z.dot(e) for e in (R.x, R.y, R.z)]  # the upward vertical in body axes
    eps = sp.sqrt(a**2 * mu[0] ** 2 + b**2 * mu[1] ** 2 + c**2 * mu[2] ** 2)
    # the lowest point of the ellipsoid centred at G + h R.z, from G
    r_gp = -(a**2) * mu[0] / eps * R.x - b**2 * mu[1] / eps * R.y + (h - c**2 * mu[2] / eps) * R.z
    z_g = -r_gp.dot(N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", x * N.x + y * N.y + z_g * N.z)
    G.set_vel(N, vx * N.x + vy * N.y + z_g.diff(t).subs(qdot) * N.z)
    v_contact = G.vel(N) + R.ang_vel_in(N).cross(r_gp)
    body = me.RigidBody("body", G, R, m, (me.inertia(R, A, B, C, ixy=D), G))
    kane = me.KanesMethod(
        N,
        q_ind=q,
        u_ind=[w1, w2, w3],
        u_dependent=[vx, vy],
        kd_eqs=kd,
        velocity_constraints=[v_contact.dot(N.x), v_contact.dot(N.y)],
    )
    kane.kanes_equations([body], [(G, -m * g * N.z)])
    spin = R.ang_vel_in(N).dot(N.z)
    energy = body.kinetic_energy(N).subs(kane.kindiffdict()) + m * g * z_g
    return kane, list(q) + list(u), (a, b, c, h, m, A, B, C, D, g), spin, energy, v_contact, N


def rattleback_minimal(params: dict | None = None):
    """``(rhs, spin, energy, complete)`` for the state s = [ψ, θ, φ, x, y, ω1, ω2, ω3, ẋ, ẏ]:
    f(t, s); the vertical component of the angular velocity and the energy at s; and
    ``complete(psi, theta, phi, w)`` giving a full state whose ẋ, ẏ satisfy the no-slip
    constraints.  ``params``: K&L's names (``KANE_LEVINSON`` by default)."""
    import sympy as sp

    kane, states, syms, spin, energy, v_contact, N = _kane()
    vals = {**KANE_LEVINSON, **(params or {})}
    sub = {s: vals[str(s)] for s in syms}
    MF = sp.lambdify(  # one function: the two share most of their subexpressions
        [states], [kane.mass_matrix_full.xreplace(sub), kane.forcing_full.xreplace(sub)], "numpy", cse=True
    )
    SP = sp.lambdify([states], sp.sympify(spin).xreplace(sub), "numpy")
    EE = sp.lambdify([states], sp.sympify(energy).xreplace(sub), "numpy", cse=True)
    # the contact point's horizontal velocity: ẋ, ẏ plus terms of the body rates
    vc = sp.Matrix([v_contact.dot(N.x), v_contact.dot(N.y)]).xreplace(sub)
    VC = sp.lambdify([states], vc, "numpy", cse=True)

    def rhs(_t, s):
        M, F = MF(s)
        return np.linalg.solve(np.asarray(M, float), np.asarray(F, float).ravel())

    def complete(psi, theta, phi, w):
        s = np.array([psi, theta, phi, 0.0, 0.0, *w, 0.0, 0.0], float)
        r0 = np.asarray(VC(s), float).ravel()  # linear in (ẋ, ẏ) with unit coefficients
        s[8:] = -r0
        return s

    return rhs, (lambda s: float(SP(s))), (lambda s: float(EE(s))), complete


def first_sign_change(t, values) -> float:
    """The first time ``values`` changes sign (linear interpolation between samples; nan: never)."""
    t, values = np.asarray(t, float), np.asarray(values, float)
    flips = np.nonzero(np.sign(values[1:]) != np.sign(values[:-1]))[0]
    if not len(flips):
        return math.nan
    i = flips[0]
    return float(t[i] - values[i] * (t[i + 1] - t[i]) / (values[i + 1] - values[i]))


def heading_turn(t, psi, sense: int = -1) -> float:
    """When the heading ψ turns round: the time of its minimum (``sense`` −1: the body first
    turned clockwise) or maximum (+1) over the samples, refined by a parabola through the
    three samples around it.  The spin itself flickers through zero several times while the
    body rocks hardest (from t ≈ 2.68 s to 2.86 s for K&L's initial state): which of those
    flickers is the first depends on how finely it is sampled, while the heading's extremum —
    where the spin, averaged over the rocking, changes sign — is well defined."""
    t, psi = np.asarray(t, float), np.asarray(psi, float)
    i = int(np.argmax(psi) if sense > 0 else np.argmin(psi))
    if not 0 < i < len(t) - 1:
        return float(t[i])
    y0, y1, y2 = psi[i - 1 : i + 2]
    shift = 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2)
    return float(t[i] + shift * (t[i + 1] - t[i]))


def reference_run(theta: float, phi: float, w: tuple[float, float, float], t_final: float, params: dict | None = None):
    """Integrate the minimal equations from x = y = ψ = 0 at the roll θ, pitch φ and body
    rates ``w`` (DOP853, rtol 1e-11, atol 1e-12), sampled every 0.5 ms: a dict of ``t``,
    ``psi``, ``spin`` (ω·e_z) and ``energy``."""
    from scipy.integrate import solve_ivp

    rhs, spin, energy, complete = rattleback_minimal(params)
    s0 = complete(0.0, theta, phi, w)
    t = np.linspace(0.0, t_final, round(t_final * 2000) + 1)
    sol = solve_ivp(rhs, (0.0, t_final), s0, method="DOP853", t_eval=t, rtol=1e-11, atol=1e-12)
    if sol.status != 0:
        raise RuntimeError(sol.message)
    return {
        "t": sol.t,
        "psi": sol.y[0],
        "spin": np.array([spin(s) for s in sol.y.T]),
        "energy": np.array([energy(s) for s in sol.y.T]),
    }
