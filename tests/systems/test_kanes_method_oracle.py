"""The nonminimal equations (both constraint models) agree with Kane's *minimal* equations
of the Appell–Hamel mechanism derived independently here by sympy.physics.mechanics'
KanesMethod (linear velocity constraints (101), (102), ż = −bφ̇; dependent u3, u4, u5) in
nmkane_core.systems.appell_hamel_oracle, which shares no code with the nonminimal derivation."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from nmkane_core.run.simulate import simulate
from nmkane_core.systems.appell_hamel_oracle import appell_hamel_minimal_rhs


@pytest.fixture(scope="module")
def oracle():
    x0 = np.array([0, 0, 0, 0, 30.0, 1, 1, 1, 5, -0.5])
    return solve_ivp(
        appell_hamel_minimal_rhs(), (0, 20), x0, method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True
    )


@pytest.mark.parametrize("model", ["nonlinear", "linear"])
def test_nonminimal_models_agree_with_kanes_method_minimal_equations_over_20s(oracle, model):
    run = simulate(
        {
            "system": "appell-hamel",
            "model": model,
            "integrator": "kutta-merson",
            "dt": 0.002,
            "t_final": 20,
            "every": 100,
        }
    )
    assert run.status == "ok"
    names = ["theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5"]
    ours = np.column_stack([run.state[k] for k in names])
    theirs = oracle.sol(run.t).T
    scale = np.maximum(1.0, np.abs(theirs))
    assert np.abs(ours - theirs).max() / 1.0 <= 1e-7 * scale.max()
    assert (np.abs(ours - theirs) / scale).max() < 1e-8


def test_nonlinear_and_linear_models_agree_with_each_other():
    runs = [
        simulate(
            {"system": "appell-hamel", "model": m, "integrator": "dop853", "rtol": 1e-12, "atol": 1e-12, "t_final": 20}
        )
        for m in ("nonlinear", "linear")
    ]
    for r in runs:
        assert r.status == "ok" and r.t[-1] == 20.0
    a = np.array([runs[0].state[k][-1] for k in runs[0].state])
    b = np.array([runs[1].state[k][-1] for k in runs[1].state])
    np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-8)
