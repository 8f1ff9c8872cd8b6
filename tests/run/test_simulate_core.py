"""Runs: compiled vs reference kernels, integrators, diagnostics, statuses, initial states."""

import json

import numpy as np
import pytest

from nmkane_core import InputError, get_system
from nmkane_core.errors import InconsistentStateError
from nmkane_core.integrate.methods import INTEGRATORS, KUTTA_MERSON, RK4
from nmkane_core.kernel.built import built
from nmkane_core.run.plan import resolve
from nmkane_core.run.simulate import kernel_for, simulate
from nmkane_core.schema import RunResult
from nmkane_core.symbolic.reference import ReferenceKernel, integrate_reference

CASES = [
    ("appell-hamel", "nonlinear"),
    ("appell-hamel", "linear"),
    ("sliding-particle", "nonminimal"),
    ("sliding-particle", "minimal"),
]


def _random_state(system, variant, rng):
    md = built(system).model(variant)
    return rng.uniform(-2, 2, 2 * md.n) + np.r_[np.zeros(md.n), np.full(md.n, 0.5)]


@pytest.mark.parametrize("name,variant", CASES)
def test_compiled_rhs_agrees_with_numpy_reference_to_1e12(name, variant):
    system = get_system(name)
    mod = kernel_for(system, variant)
    ref = ReferenceKernel(built(system).derivation(variant))
    rng = np.random.default_rng(7)
    md = built(system).model(variant)
    for _ in range(50):
        x = _random_state(system, variant, rng)
        p = np.array(
            [rng.uniform(0.5, 2) * prm.default if prm.default else rng.uniform(-1, 1) for prm in system.parameters]
        )
        G = rng.uniform(-5, 0, (len(md.nonholonomic),) * 2)
        G1 = rng.uniform(-30, 0, (len(md.holonomic),) * 2)
        G2 = rng.uniform(-100, 0, (len(md.holonomic),) * 2)
        got, _, _ = mod.rhs(0.3, x, p, G, G1, G2)
        want = ref.rhs(0.3, x, p, G, G1, G2)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("name,variant", CASES)
@pytest.mark.parametrize("tableau", [RK4, KUTTA_MERSON])
def test_compiled_trajectory_agrees_with_reference_loop(name, variant, tableau):
    system = get_system(name)
    option = system.option
    run = simulate(
        {
            "system": name,
            option: variant,
            "integrator": tableau.name,
            "dt": 0.01,
            "t_final": 1.0,
            "gamma1": -20 if name == "sliding-particle" else None,
            "gamma2": -100 if name == "sliding-particle" else None,
        }
    )
    plan = resolve(run.settings)
    ref = ReferenceKernel(built(system).derivation(variant))
    t, xs = integrate_reference(ref, plan.x0, plan.p, 0.01, 100, tableau, plan.G, plan.G1, plan.G2)
    md = built(system).model(variant)
    ours = np.column_stack([run.state[str(s)] for s in md.q + md.u])
    np.testing.assert_allclose(run.t, t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ours, xs, rtol=1e-11, atol=1e-11)


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_every_integrator_reaches_t_final_with_finite_results(integrator):
    run = simulate(
        {"system": "appell-hamel", "integrator": integrator, "dt": 0.01, "t_final": 5, "rtol": 1e-8, "atol": 1e-10}
    )
    assert run.status == "ok", run.summary["message"]
    assert run.t[0] == 0 and abs(run.t[-1] - 5) < 1e-12
    for arr in [run.t, run.energy, *run.state.values(), *run.violation.values()]:
        assert np.all(np.isfinite(arr))
    assert run.summary["max_abs_energy_drift"] < 1e-4


def test_adaptive_kutta_merson_meets_tolerance_against_fine_fixed_step():
    fine = simulate({"system": "appell-hamel", "dt": 0.0005, "t_final": 20, "every": 40000})
    adapt = simulate(
        {"system": "appell-hamel", "integrator": "kutta-merson-adaptive", "t_final": 20, "rtol": 1e-10, "atol": 1e-12}
    )
    assert adapt.summary["steps"] < 5000
    for k in ("theta", "phi", "u2"):
        assert abs(adapt.state[k][-1] - fine.state[k][-1]) < 1e-7 * max(1, abs(fine.state[k][-1]))


def test_every_thins_output_but_not_the_summary():
    a = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 50})
    b = simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 50, "every": 7})
    assert len(b.t) == 5000 // 7 + 2  # rows every 7 steps, the initial and the final row
    assert b.t[-1] == 50.0
    assert a.summary["max_abs_violation"] == b.summary["max_abs_violation"]
    assert a.summary["max_abs_energy_drift"] == b.summary["max_abs_energy_drift"]


def test_singular_start_of_nonlinear_model_is_reported_not_integrated():
    run = simulate({"system": "appell-hamel", "model": "nonlinear", "initial": {"u2": 0.0}, "switching": False})
    assert run.status == "singular"
    assert "J2" in run.summary["message"] and "t = 0" in run.summary["message"]
    assert all(np.all(np.isfinite(v)) for v in run.state.values())


@pytest.mark.parametrize("bound", [None, 1e300])
def test_diverging_run_stops_with_status_and_finite_data(bound):
    """A destabilizing gain with a large step blows up: reported, never NaN in the result.  The
    default energy bound (10⁶ × the initial energy scale) stops it ``drifted`` at the first state
    past it; without it the run goes on until the state is no longer finite (``diverged``)."""
    req = {"system": "sliding-particle", "gamma1": 500, "gamma2": 5000, "dt": 0.05, "t_final": 200}
    run = simulate({**req, "max_energy_drift": bound}, progress=False)
    if bound is None:
        assert run.status == "drifted" and "past the run's bound" in run.summary["message"]
        limit = run.summary["bounds"]["energy_drift"]
        assert limit == pytest.approx(1e6 * 9.81)  # |E0| = 9.81 J, at rest
        assert limit < run.summary["max_abs_energy_drift"] < 1e20  # stopped at the first state past it
    else:
        assert run.status == "diverged" and run.summary["bounds"]["energy_drift"] == 1e300
    assert all(np.all(np.isfinite(v)) for v in run.state.values())
    assert np.all(np.isfinite(run.energy))
    assert any("not stable" in w for w in run.summary["warnings"])


def test_time_limit_returns_partial_run_with_status_timeout():
    run = simulate({"system": "appell-hamel", "dt": 0.0001, "t_final": 5000, "every": 1000}, time_limit=0.05)
    assert run.status == "timeout"
    assert 0 < run.t[-1] < 5000


def test_document_has_contract_keys_and_round_trips():
    run = simulate({"system": "appell-hamel", "dt": 0.05, "t_final": 1})
    doc = json.loads(run.document().model_dump_json(by_alias=True))
    assert set(doc) >= {"system", "settings", "t", "state", "energy", "violation", "summary"}
    assert set(doc["state"]) == {"theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5"}
    assert set(doc["violation"]) == {"rolling_speed", "no_side_slip", "thread"}
    assert set(doc["summary"]) >= {
        "status",
        "message",
        "steps",
        "rhs_evals",
        "wall_time_s",
        "max_abs_violation",
        "max_abs_energy_drift",
        "final_energy_drift",
    }
    assert doc["settings"]["model"] == "nonlinear" and doc["settings"]["params"]["rho"] == 5.0
    RunResult.model_validate(doc)
    # the resolved settings re-run to the same result
    again = simulate(doc["settings"])
    assert again.state["phi"][-1] == run.state["phi"][-1]


@pytest.mark.parametrize(
    "settings",
    [
        {"system": "sliding-particle", "formulation": "minimal"},
        {"system": "sliding-particle"},
        {"system": "appell-hamel"},
        {"system": "appell-hamel", "integrator": "dop853"},
    ],
)
def test_result_arrays_are_contiguous_float64(settings):
    """Found by the soak test: an output column of the minimal formulation was a strided view,
    which fast JSON encoders refuse."""
    run = simulate({**settings, "t_final": 1})
    for arr in [run.t, run.energy, *run.state.values(), *run.violation.values()]:
        assert arr.dtype == np.float64 and arr.flags["C_CONTIGUOUS"]


def test_minimal_formulation_reports_y_u2_and_satisfies_the_surface():
    run = simulate({"system": "sliding-particle", "formulation": "minimal", "dt": 0.01, "t_final": 10})
    assert set(run.state) == {"x", "y", "u1", "u2"}
    np.testing.assert_allclose(run.state["y"], 1 - run.state["x"] ** 2, atol=1e-14)
    assert run.summary["max_abs_violation"]["surface"] == 0.0


# ---------------------------------------------------------------- initial states
def test_completion_from_independent_speeds_satisfies_both_models():
    system = get_system("appell-hamel")
    params = system.resolve_params({})
    plan = resolve({"system": "appell-hamel", "initial": {"u1": 0.3, "u2": -2.0, "theta": 0.7}})
    full = plan.initial
    th, u1, u2 = 0.7, 0.3, -2.0
    # rolling (51)–(54): ẋ = aφ̇cosθ − ρθ̇ sinθ, ẏ = aφ̇ sinθ + ρθ̇ cosθ, ż = −bφ̇
    assert abs(full["u3"] - (u2 * np.cos(th) - 5 * u1 * np.sin(th))) < 1e-12
    assert abs(full["u4"] - (u2 * np.sin(th) + 5 * u1 * np.cos(th))) < 1e-12
    assert abs(full["u5"] + 0.5 * u2) < 1e-12
    assert params["rho"] == 5


def test_full_inconsistent_state_is_refused_with_residuals():
    full = {"theta": 0, "phi": 0, "x": 0, "y": 0, "z": 30, "u1": 1, "u2": 1, "u3": 1.1, "u4": 5, "u5": -0.5}
    with pytest.raises(InconsistentStateError) as e:
        resolve({"system": "appell-hamel", "initial": full})
    assert "rolling_x" in str(e.value)


def test_full_consistent_state_is_accepted_unchanged():
    full = {"theta": 0, "phi": 0, "x": 0, "y": 0, "z": 30, "u1": 1, "u2": 1, "u3": 1, "u4": 5, "u5": -0.5}
    plan = resolve({"system": "appell-hamel", "model": "linear", "initial": full})
    assert plan.initial == {k: float(v) for k, v in full.items()}


@pytest.mark.parametrize(
    "settings,field",
    [
        ({"system": "nope"}, "system"),
        ({"system": "appell-hamel", "model": "quadratic"}, "model"),
        ({"system": "appell-hamel", "formulation": "minimal"}, "formulation"),
        ({"system": "appell-hamel", "dt": 0}, "dt"),
        ({"system": "appell-hamel", "dt": -0.1}, "dt"),
        ({"system": "appell-hamel", "t_final": 0}, "t_final"),
        ({"system": "appell-hamel", "dt": 1e-6, "t_final": 1e3}, "dt"),
        ({"system": "appell-hamel", "integrator": "euler"}, "integrator"),
        ({"system": "appell-hamel", "params": {"rho": -1}}, "params.rho"),
        ({"system": "appell-hamel", "params": {"mass": 1}}, "params.mass"),
        ({"system": "appell-hamel", "initial": {"w": 1}}, "initial.w"),
        ({"system": "appell-hamel", "gamma": [[1, 2]]}, "gamma"),
    ],
)
def test_bad_input_names_the_field(settings, field):
    with pytest.raises(InputError) as e:
        resolve(settings)
    assert e.value.field == field
    assert "allowed" in str(e.value)


def test_nan_and_infinity_are_refused_by_the_schema():
    for bad in (float("nan"), float("inf")):
        with pytest.raises(InputError) as e:
            resolve({"system": "appell-hamel", "dt": bad})
        assert e.value.field == "dt"


def test_catalog_lists_the_projections_the_schema_accepts():
    from typing import get_args

    from nmkane_core.run.catalog import catalog
    from nmkane_core.schema import RunSettings

    choices = get_args(RunSettings.model_fields["projection"].annotation)[0]  # Optional[...]: the system's default
    assert catalog()["projections"] == list(get_args(choices))


def test_simulate_module_still_exports_its_public_names():
    import importlib

    sim = importlib.import_module("nmkane_core.run.simulate")  # the package's ``simulate`` is the function
    for name in (
        "Plan",
        "Run",
        "resolve",
        "simulate",
        "simulate_many",
        "kernel_for",
        "catalog",
        "prepare",
        "validate_settings",
    ):
        assert name in sim.__all__ and callable(getattr(sim, name)), name


def test_the_generated_kernels_use_the_one_definition_of_the_loop_constants():
    from nmkane_core.kernel import constants

    mod = kernel_for(get_system("sliding-particle"), "nonminimal")
    for name in constants.NAMES:
        assert getattr(mod, name) == getattr(constants, name), name
    from nmkane_core.kernel.core import header

    assert "#define STATUS_OK 0" in header()  # the compiled core's, generated from the same module


def test_a_finished_run_cuts_non_finite_rows_and_reports_overflowed_maxima_as_finite():
    """The core's guarantee (nmkane_core.run.finish): rows from the first non-finite one on are
    cut and the run ends diverged; a summary number that overflowed is reported as the largest
    finite one and named in a warning — the document is always valid JSON of the schema."""
    import sys

    from nmkane_core.integrate.drivers import integrate
    from nmkane_core.run.finish import _finite_rows, _validated
    from nmkane_core.run.plan import resolve
    from nmkane_core.run.simulate import prepare

    plan = resolve({"system": "appell-hamel", "dt": 0.01, "t_final": 0.1})
    prepare(plan)

    class Bar:
        def update(self, t):
            pass

    out = integrate(plan.job(), Bar())
    out.x[5, 6] = float("nan")
    outputs = np.empty((out.x.shape[0], 0))
    cut, _, overflow = _finite_rows(plan, out, outputs)
    assert overflow and cut.t.size == 5 and cut.x.shape[0] == 5 and cut.t_end == out.t[4]
    summary = _validated(
        {
            "status": "diverged",
            "message": "",
            "steps": 1,
            "rhs_evals": 1,
            "wall_time_s": 0.0,
            "t_end": 0.1,
            "max_abs_violation": {"thread": float("-inf")},
            "max_abs_energy_drift": float("inf"),
            "final_energy_drift": 0.0,
        }
    )
    assert summary["max_abs_energy_drift"] == sys.float_info.max
    assert summary["max_abs_violation"]["thread"] == -sys.float_info.max
    assert "max_abs_violation.thread" in summary["warnings"][0]
