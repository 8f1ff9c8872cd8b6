"""An independent derivation for cross-checks and benchmarks: Kane's *minimal* equations
of the Appell–Hamel mechanism from sympy.physics.mechanics' KanesMethod.

Linear velocity constraints (101), (102) and ż = −bφ̇ (the derivative of (59)), dependent
speeds u3, u4, u5 — built from bodies and loads only, sharing nothing with
`nmkane_core.symbolic.derivation`.  ``rhs`` is "the usual sympy route": lambdify
``mass_matrix_full`` and ``forcing_full`` and solve with numpy at every call.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp
from sympy.physics import mechanics as me

DEFAULTS = dict(a=1.0, b=0.5, rho=5.0, m=1.0, M=5.0, I=2.5, g=9.81)


@cache
def _kane():
    th, ph, x, y, z = q = me.dynamicsymbols("th ph x y z")
    u = me.dynamicsymbols("w1:6")
    a, b, rho, m, M, I, g = sp.symbols("a b rho m M I g")
    N = me.ReferenceFrame("N")
    H = N.orientnew("H", "Axis", (th, N.z))
    W = H.orientnew("W", "Axis", (ph, H.y))
    W.set_ang_vel(N, u[0] * N.z + u[1] * H.y)
    O = me.Point("O")
    O.set_vel(N, 0)
    load = O.locatenew("L", x * N.x + y * N.y + z * N.z)
    load.set_vel(N, u[2] * N.x + u[3] * N.y + u[4] * N.z)
    centre = O.locatenew("C", (x - rho * sp.cos(th)) * N.x + (y - rho * sp.sin(th)) * N.y + a * N.z)
    centre.set_vel(N, (u[2] + rho * u[0] * sp.sin(th)) * N.x + (u[3] - rho * u[0] * sp.cos(th)) * N.y)
    wheel = me.RigidBody("W", centre, W, M, (me.inertia(W, I, I, I), centre))
    bob = me.Particle("B", load, m)
    t = me.dynamicsymbols._t
    kd = [qi.diff(t) - ui for qi, ui in zip(q, u, strict=True)]
    vc = [
        a * u[1] * sp.cos(th) - u[2] - rho * u[0] * sp.sin(th),
        a * u[1] * sp.sin(th) - u[3] + rho * u[0] * sp.cos(th),
        u[4] + b * u[1],
    ]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u[:2], u_dependent=u[2:], kd_eqs=kd, velocity_constraints=vc)
    kane.kanes_equations([wheel, bob], [(load, -m * g * N.z), (centre, -M * g * N.z)])
    return kane, list(q) + list(u), (a, b, rho, m, M, I, g)


def appell_hamel_minimal_rhs(**params):
    """f(t, s) for s = [θ, φ, x, y, z, u1..u5] from KanesMethod + lambdify + numpy.linalg.solve."""
    kane, states, syms = _kane()
    vals = dict(DEFAULTS)
    vals.update(params)
    sub = {s: vals[str(s)] for s in syms}
    MM = sp.lambdify([states], kane.mass_matrix_full.subs(sub), "numpy")
    FF = sp.lambdify([states], kane.forcing_full.subs(sub), "numpy")

    def rhs(t, s):
        return np.linalg.solve(np.asarray(MM(s), float), np.asarray(FF(s), float).ravel())

    return rhs
