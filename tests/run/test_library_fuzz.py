"""Property-based fuzzing of the library API: random parameters, gains, steps, initial
speeds and integrators never give status 'ok' with non-finite numbers, always give a
status and a message, and never run past the time limit."""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nmkane_core import InputError
from nmkane_core.run.simulate import simulate

FINITE = dict(allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    model=st.sampled_from(["nonlinear", "linear"]),
    integrator=st.sampled_from(["rk4", "kutta-merson", "kutta-merson-adaptive", "rk45", "dop853"]),
    dt=st.floats(1e-3, 0.3),
    t_final=st.floats(0.01, 30),
    gamma=st.floats(-50, 50, **FINITE),
    u1=st.floats(-20, 20, **FINITE),
    u2=st.floats(-20, 20, **FINITE),
    rho=st.floats(0.01, 50),
    a=st.floats(0.01, 10),
    b=st.floats(0.01, 10),
    g=st.floats(0, 100),
    switching=st.booleans(),
)
def test_appell_hamel_runs_never_report_ok_with_nonfinite_values(
    model, integrator, dt, t_final, gamma, u1, u2, rho, a, b, g, switching
):
    settings_ = {
        "system": "appell-hamel",
        "model": model,
        "integrator": integrator,
        "dt": dt,
        "t_final": t_final,
        "gamma": gamma,
        "initial": {"u1": u1, "u2": u2},
        "params": {"rho": rho, "a": a, "b": b, "g": g},
        "switching": switching,
        "rtol": 1e-6,
        "atol": 1e-8,
    }
    _check(settings_)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    formulation=st.sampled_from(["nonminimal", "minimal"]),
    integrator=st.sampled_from(["rk4", "kutta-merson", "kutta-merson-adaptive", "radau"]),
    dt=st.floats(1e-3, 0.5),
    t_final=st.floats(0.01, 50),
    gamma1=st.floats(-1e3, 1e3, **FINITE),
    gamma2=st.floats(-1e4, 1e4, **FINITE),
    x0=st.floats(-5, 5, **FINITE),
    u0=st.floats(-50, 50, **FINITE),
    projection=st.sampled_from(["none", "blajer", "yoon"]),
    l0=st.floats(0.01, 10),
)
def test_sliding_particle_runs_never_report_ok_with_nonfinite_values(
    formulation, integrator, dt, t_final, gamma1, gamma2, x0, u0, projection, l0
):
    if integrator == "radau":
        projection = "none"
    settings_ = {
        "system": "sliding-particle",
        "formulation": formulation,
        "integrator": integrator,
        "dt": dt,
        "t_final": t_final,
        "gamma1": gamma1,
        "gamma2": gamma2,
        "initial": {"x": x0, "u1": u0},
        "projection": projection,
        "params": {"l0": l0},
        "rtol": 1e-6,
        "atol": 1e-8,
    }
    _check(settings_)


def _check(settings_):
    try:
        run = simulate(settings_, progress=False, time_limit=2.0)
    except InputError as e:  # refused up front, with a field and a reason
        assert e.field and "allowed" in str(e)
        return
    s = run.summary
    assert s["wall_time_s"] < 4.0  # the time limit is honoured (kernel loading excluded)
    assert s["status"] in ("ok", "singular", "diverged", "drifted", "timeout", "failed") and s["message"]
    arrays = [run.t, *run.state.values(), *run.violation.values()]
    if run.energy is not None:
        arrays.append(run.energy)
    for arr in arrays:
        assert np.all(np.isfinite(arr)), s
    for v in s["max_abs_violation"].values():
        assert math.isfinite(v)
    if s["status"] == "ok":
        assert abs(run.t[-1] - settings_["t_final"]) <= 1e-9 * max(1, settings_["t_final"])
