"""The Whipple bicycle through "the usual sympy route", for ``nmkane bench``: KanesMethod on
the same bodies and loads (eight speeds, unconstrained), the constraints' Jacobian and
velocity term by sympy differentiation, everything lambdified; at each call the dependent
speeds' accelerations come from a numeric solve of [M Jᵀ; J 0][u̇; λ] = [F; −b]
(Lagrange multipliers — the same motion as the nonminimal equations on the manifold).
"""

from __future__ import annotations

import numpy as np

from .whipple_bicycle import PARAMETERS, _mechanics


def bicycle_sympy_rhs(params: dict | None = None):
    """f(t, x) for x = [q1..q8, u1..u8]: KanesMethod + lambdify + numpy.linalg.solve per call."""
    import sympy as sp
    from sympy.physics import mechanics as me

    m = _mechanics()
    q, u = list(m["q"]), list(m["u"])
    t = me.dynamicsymbols._t
    kane = me.KanesMethod(m["N"], q_ind=q, u_ind=u, kd_eqs=m["kd"])
    kane.kanes_equations(m["bodies"], m["loads"])
    qd = {qi.diff(t): ui for qi, ui in zip(q, u, strict=True)}
    phi = sp.Matrix(list(m["nonholonomic"].values()) + [e.diff(t).xreplace(qd) for e in m["holonomic"].values()])
    J = phi.jacobian(u)
    ud = [ui.diff(t) for ui in u]
    phid = phi.diff(t).xreplace(qd)
    b = phid.xreplace(dict.fromkeys(ud, 0))
    values = {k: p.default for k, p in PARAMETERS.items()} | dict(params or {})
    sub = {s: values[s.name] for s in m["par"]}
    args = [q + u]
    MM = sp.lambdify(args, kane.mass_matrix.xreplace(sub), "numpy", cse=True)
    FF = sp.lambdify(args, kane.forcing.xreplace(sub), "numpy", cse=True)
    JJ = sp.lambdify(args, J.xreplace(sub), "numpy", cse=True)
    BB = sp.lambdify(args, b.xreplace(sub), "numpy", cse=True)
    n, k = len(u), J.shape[0]

    def rhs(_t, x):
        M = np.asarray(MM(x), float)
        Jn = np.asarray(JJ(x), float)
        K = np.zeros((n + k, n + k))
        K[:n, :n], K[:n, n:], K[n:, :n] = M, Jn.T, Jn
        r = np.concatenate([np.asarray(FF(x), float).ravel(), -np.asarray(BB(x), float).ravel()])
        return np.concatenate([x[n:], np.linalg.solve(K, r)[:n]])

    return rhs


def bicycle_sympy_forces(params: dict | None = None):
    """An independent route to the bicycle's constraint forces (tests): KanesMethod on the
    unconstrained bodies and loads, the multiplier system [M Jᵀ; J 0][u̇; μ] = [F; −b] solved
    with numpy, and the kinematics of the material contact points and the mass centres by
    sympy differentiation.

    Returns ``at(x)`` for x = [q1..q8, u1..u8], giving a dict: ``ud`` (u̇), ``Fc`` = M u̇ − F
    (the generalized constraint force), ``Jr``, ``Jf`` (3×8: ∂v/∂u of the rear and front
    wheels' material contact points, N components), ``momentum_rate`` (Σ m a_G, N components)
    and ``weight`` (Σ m g N.z)."""
    import sympy as sp
    from sympy.physics import mechanics as me

    m = _mechanics()
    q, u = list(m["q"]), list(m["u"])
    t = me.dynamicsymbols._t
    N = m["N"]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=m["kd"])
    kane.kanes_equations(m["bodies"], m["loads"])
    qd = {qi.diff(t): ui for qi, ui in zip(q, u, strict=True)}
    phi = sp.Matrix(list(m["nonholonomic"].values()) + [e.diff(t).xreplace(qd) for e in m["holonomic"].values()])
    J = phi.jacobian(u)
    ud = [ui.diff(t) for ui in u]
    b = phi.diff(t).xreplace(qd).xreplace(dict.fromkeys(ud, 0))
    par, Jr, Jf, rate, weight = _contact_kinematics(u, qd)
    values = {k: p.default for k, p in PARAMETERS.items()} | dict(params or {})
    sub = {sym: values[sym.name] for sym in m["par"]} | {sym: values[sym.name] for sym in par}
    udot = sp.symbols("ud1:9")
    rate = rate.xreplace(dict(zip(ud, udot, strict=True)))
    args = [q + u]
    fns = {
        k: sp.lambdify(args, e.xreplace(sub), "numpy", cse=True)
        for k, e in (("M", kane.mass_matrix), ("F", kane.forcing), ("J", J), ("b", b), ("Jr", Jr), ("Jf", Jf))
    }
    rate_fn = sp.lambdify([q + u, list(udot)], rate.xreplace(sub), "numpy", cse=True)
    w = np.asarray(weight.xreplace(sub), float).ravel()
    n = len(u)

    def at(x):
        x = list(np.asarray(x, float))
        M = np.asarray(fns["M"](x), float)
        Fv = np.asarray(fns["F"](x), float).ravel()
        Jn = np.asarray(fns["J"](x), float)
        k = Jn.shape[0]
        K = np.zeros((n + k, n + k))
        K[:n, :n], K[:n, n:], K[n:, :n] = M, Jn.T, Jn
        sol = np.linalg.solve(K, np.concatenate([Fv, -np.asarray(fns["b"](x), float).ravel()]))
        udv = sol[:n]
        return {
            "ud": udv,
            "Fc": M @ udv - Fv,
            "Jr": np.asarray(fns["Jr"](x), float),
            "Jf": np.asarray(fns["Jf"](x), float),
            "momentum_rate": np.asarray(rate_fn(x, list(udv)), float).ravel(),
            "weight": w,
        }

    return at


def _contact_kinematics(u, qd):
    """The bicycle's geometry with its velocities set again (its own frames and points: nothing
    shared with ``_mechanics``' objects): the parameters, ∂v/∂u of the rear and front material
    contact points, Σ m a_G and the weight (N components)."""
    import sympy as sp

    from .whipple_bicycle import _geometry

    _, _, par, fr, pt, (_, _, _, root) = _geometry()
    P = dict(zip([s.name for s in par], par, strict=True))
    A, B, C, D, E, F = (fr[k] for k in ("A", "B", "C", "D", "E", "F"))
    NN = fr["N"]
    A.set_ang_vel(NN, u[2] * NN.z)
    B.set_ang_vel(A, u[3] * A.x)
    C.set_ang_vel(B, u[4] * B.y)
    D.set_ang_vel(C, u[5] * C.y)
    E.set_ang_vel(C, u[6] * C.z)
    F.set_ang_vel(E, u[7] * E.y)
    pt["O"].set_vel(NN, 0)
    pt["dn"].set_vel(NN, u[0] * NN.x + u[1] * NN.y)
    pt["do"].v2pt_theory(pt["dn"], NN, B)
    pt["ce"].v2pt_theory(pt["do"], NN, C)
    pt["bo"].v2pt_theory(pt["do"], NN, C)
    pt["fo"].v2pt_theory(pt["ce"], NN, E)
    pt["ho"].v2pt_theory(pt["ce"], NN, E)
    s = E.y.dot(A.z)
    v_rear = pt["do"].vel(NN) + D.ang_vel_in(NN).cross(P["rR"] * B.z)
    v_front = pt["fo"].vel(NN) + F.ang_vel_in(NN).cross(P["rF"] * (A.z - s * E.y) / root)
    Jr = v_rear.to_matrix(NN).jacobian(u)
    Jf = v_front.to_matrix(NN).jacobian(u)
    masses = [(pt["do"], P["mR"]), (pt["bo"], P["mB"]), (pt["ho"], P["mH"]), (pt["fo"], P["mF"])]
    rate = sum((mass * p.acc(NN).to_matrix(NN) for p, mass in masses), sp.zeros(3, 1)).xreplace(qd)
    weight = sum(mass for _, mass in masses) * P["g"] * sp.Matrix([0, 0, 1])
    return par, Jr, Jf, rate, weight
