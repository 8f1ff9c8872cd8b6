"""Post-step corrections (Blajer 2002 / Yoon, Howe & Greenwood 1994 family)."""

import pytest

from nmkane_core import InputError
from nmkane_core.run.plan import resolve
from nmkane_core.run.simulate import simulate


@pytest.mark.parametrize("projection", ["blajer", "yoon"])
def test_projection_keeps_particle_on_the_surface_to_roundoff(projection):
    run = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 200, "projection": projection, "every": 100})
    assert run.status == "ok"
    assert run.summary["max_abs_violation"]["surface"] < 1e-13
    # without the correction the same run drifts by orders of magnitude more
    plain = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 200, "every": 100})
    assert plain.summary["max_abs_violation"]["surface"] > 1e6 * run.summary["max_abs_violation"]["surface"]


def test_blajer_preset_restores_energy_and_yoon_does_not_by_default():
    b = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 100, "projection": "blajer"})
    y = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 100, "projection": "yoon"})
    assert b.summary["max_abs_energy_drift"] < 1e-12
    assert y.summary["max_abs_energy_drift"] > 1e-8


@pytest.mark.parametrize("model", ["nonlinear", "linear"])
def test_projection_on_appell_hamel_satisfies_every_constraint(model):
    run = simulate({"system": "appell-hamel", "model": model, "dt": 0.02, "t_final": 20, "projection": "yoon"})
    assert run.status == "ok"
    assert max(run.summary["max_abs_violation"].values()) < 1e-11


def test_projection_does_not_change_the_motion_beyond_integration_error():
    ref = simulate({"system": "appell-hamel", "dt": 0.001, "t_final": 10, "every": 10000})
    proj = simulate({"system": "appell-hamel", "dt": 0.01, "t_final": 10, "projection": "blajer", "every": 1000})
    for k in ("theta", "phi", "x", "y"):
        assert abs(proj.state[k][-1] - ref.state[k][-1]) < 1e-6 * max(1, abs(ref.state[k][-1]))


def test_switches_are_recorded_in_resolved_settings():
    plan = resolve(
        {
            "system": "sliding-particle",
            "projection": "yoon",
            "projection_iterations": 1,
            "projection_jacobian": "frozen",
        }
    )
    assert plan.settings["projection_weight"] == "mass"
    assert plan.settings["projection_iterations"] == 1
    assert plan.settings["projection_jacobian"] == "frozen"
    run = simulate(plan)
    assert run.status == "ok" and run.summary["max_abs_violation"]["surface"] < 1e-10


def test_projection_with_scipy_integrator_is_refused():
    with pytest.raises(InputError) as e:
        resolve({"system": "sliding-particle", "projection": "blajer", "integrator": "dop853"})
    assert e.value.field == "projection"
