"""The paper's simulation claims that the core library must reproduce (issue 2)."""

import numpy as np
import pytest

from nmkane_core.simulate import simulate


def test_damped_particle_bound_matches_paper_fig15():
    """Γ1 = −20, Γ2 = −100, Kutta–Merson, Δt = 0.001, 500 s: max|φ| < 2.0e−11 (≈1.8e−11)."""
    run = simulate({"system": "sliding-particle", "gamma1": -20, "gamma2": -100, "dt": 0.001,
                    "t_final": 500, "integrator": "kutta-merson", "every": 1000})
    assert run.status == "ok" and run.summary["steps"] == 500_000
    bound = run.summary["max_abs_violation"]["surface"]
    assert 1.0e-11 < bound < 2.0e-11


@pytest.fixture(scope="module")
def undamped():
    return {dt: simulate({"system": "sliding-particle", "dt": dt, "t_final": 500, "every": 10})
            for dt in (0.01, 0.001)}


def test_undamped_particle_violation_grows_with_time_figs_11_12(undamped):
    for dt, run in undamped.items():
        v = np.abs(run.violation["surface"])
        n = len(v)
        first, last = v[: n // 5].max(), v[-n // 5:].max()
        assert last > 3 * first, (dt, first, last)


def test_undamped_particle_violation_smaller_for_smaller_step_figs_11_12(undamped):
    big = undamped[0.01].summary["max_abs_violation"]["surface"]
    small = undamped[0.001].summary["max_abs_violation"]["surface"]
    assert small < big / 1e4


@pytest.mark.parametrize("dt", [0.01, 0.05, 0.1])
@pytest.mark.parametrize("t_final", [20, 100])
def test_nonlinear_model_energy_drift_smaller_than_linear_fig9(dt, t_final):
    drift = {}
    for model in ("nonlinear", "linear"):
        run = simulate({"system": "appell-hamel", "model": model, "dt": dt, "t_final": t_final,
                        "integrator": "kutta-merson", "every": 10})
        assert run.status == "ok"
        drift[model] = run.summary["max_abs_energy_drift"]
    assert drift["nonlinear"] < drift["linear"]


def test_appell_hamel_qualitative_motion():
    """θ tends to a constant, θ̇ → 0, φ̇ grows as the load falls (REFERENCE.md)."""
    run = simulate({"system": "appell-hamel", "dt": 0.01, "t_final": 20})
    u1, u2, z = run.state["u1"], run.state["u2"], run.state["z"]
    assert abs(u1[-1]) < 1e-6 and u2[-1] > 5 * u2[0] and z[-1] < z[0]
    assert np.all(np.diff(u2) > 0)
