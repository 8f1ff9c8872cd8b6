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
