"""The nonminimal equations (both constraint models) agree with Kane's *minimal* equations
of the Appell–Hamel mechanism derived independently here by sympy.physics.mechanics'
KanesMethod (linear velocity constraints (101), (102), ż = −bφ̇; dependent u3, u4, u5)."""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp
from sympy.physics import mechanics as me

from nmkane_core.simulate import simulate

PARAMS = dict(a=1.0, b=0.5, rho=5.0, m=1.0, M=5.0, I=2.5, g=9.81)


def _oracle_rhs():
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
    kd = [qi.diff(t) - ui for qi, ui in zip(q, u)]
    vc = [a * u[1] * sp.cos(th) - u[2] - rho * u[0] * sp.sin(th),
          a * u[1] * sp.sin(th) - u[3] + rho * u[0] * sp.cos(th),
          u[4] + b * u[1]]
    kane = me.KanesMethod(N, q_ind=q, u_ind=u[:2], u_dependent=u[2:], kd_eqs=kd, velocity_constraints=vc)
    kane.kanes_equations([wheel, bob], [(load, -m * g * N.z), (centre, -M * g * N.z)])
    vals = {a: PARAMS["a"], b: PARAMS["b"], rho: PARAMS["rho"], m: PARAMS["m"], M: PARAMS["M"],
            I: PARAMS["I"], g: PARAMS["g"]}
    MM = sp.lambdify([q + u], kane.mass_matrix_full.subs(vals), "numpy")
    FF = sp.lambdify([q + u], kane.forcing_full.subs(vals), "numpy")
    return lambda t, s: np.linalg.solve(np.asarray(MM(s), float), np.asarray(FF(s), float).ravel())


@pytest.fixture(scope="module")
def oracle():
    x0 = np.array([0, 0, 0, 0, 30.0, 1, 1, 1, 5, -0.5])
    return solve_ivp(_oracle_rhs(), (0, 20), x0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)


@pytest.mark.parametrize("model", ["nonlinear", "linear"])
def test_nonminimal_models_agree_with_kanes_method_minimal_equations_over_20s(oracle, model):
    run = simulate({"system": "appell-hamel", "model": model, "integrator": "kutta-merson",
                    "dt": 0.002, "t_final": 20, "every": 100})
    assert run.status == "ok"
    names = ["theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5"]
    ours = np.column_stack([run.state[k] for k in names])
    theirs = oracle.sol(run.t).T
    scale = np.maximum(1.0, np.abs(theirs))
    assert np.abs(ours - theirs).max() / 1.0 <= 1e-7 * scale.max()
    assert (np.abs(ours - theirs) / scale).max() < 1e-8


def test_nonlinear_and_linear_models_agree_with_each_other():
    runs = [simulate({"system": "appell-hamel", "model": m, "integrator": "dop853", "rtol": 1e-12,
                      "atol": 1e-12, "t_final": 20}) for m in ("nonlinear", "linear")]
    for r in runs:
        assert r.status == "ok" and r.t[-1] == 20.0
    a = np.array([runs[0].state[k][-1] for k in runs[0].state])
    b = np.array([runs[1].state[k][-1] for k in runs[1].state])
    np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8)
