"""The estimated global error (``RunSettings.error_estimate``, nmkane_core.run.accuracy): against
the exact motion of the IFToMM A01 pendulum it is within a few per cent of the true error, for
fixed-step and adaptive methods; it shrinks by 2^p when dt halves; a refined run that does not
reach its end is reported in words, never as numbers; both runs share the time limit."""

from __future__ import annotations

import numpy as np
import pytest

from nmkane_core import simulate
from nmkane_core.errors import InputError
from nmkane_core.run.accuracy import add_error_estimate
from nmkane_core.run.plan import resolve
from nmkane_core.run.sampling import interpolate
from nmkane_core.schema import LIMITS, RunSummary
from nmkane_core.systems.iftomm_a01 import exact_motion

#: the pendulum released horizontal, 10 s (its exact motion: iftomm_a01.exact_motion)
PENDULUM = {"system": "iftomm-a01", "t_final": 10.0, "dt": 0.01, "error_estimate": True}
STATES = ("x", "y", "u1", "u2")


def true_error(run) -> dict[str, float]:
    """The largest |x − x_exact| of each state over the run's rows."""
    exact = dict(zip(STATES, exact_motion(run.t), strict=True))
    return {k: float(np.max(np.abs(run.state[k] - exact[k]))) for k in STATES}


@pytest.mark.parametrize("integrator", ["kutta-merson", "rk4"])
def test_a_fixed_step_estimate_is_the_true_error_of_the_exact_motion(integrator):
    run = simulate({**PENDULUM, "integrator": integrator}, progress=False)
    est = run.summary["error_estimate"]
    assert run.status == "ok" and est["refined_status"] == "ok" and est["method"] == "half step"
    assert est["refined"] == {"dt": 0.005, "every": 2} and est["order"] == 4 and est["rows"] == run.t.size
    true = true_error(run)
    assert min(true.values()) > 1e-7  # truncation, far above round-off: the comparison means something
    for k in STATES:
        assert 0.85 < est["max_abs"][k] / true[k] < 1.0, (k, est["max_abs"][k], true[k])  # (1 − 2⁻⁴) of it
        assert est["richardson"][k] == pytest.approx(est["max_abs"][k] * 16 / 15)
        assert 0.95 < est["richardson"][k] / true[k] < 1.05, (k, est["richardson"][k], true[k])
    RunSummary.model_validate(run.summary)


@pytest.mark.parametrize("integrator", ["kutta-merson-adaptive", "dop853"])
def test_an_adaptive_estimate_is_near_the_true_error_of_the_exact_motion(integrator):
    """rtol/10: the refined run's error is a tenth of the run's, so the difference is ~0.9 of it.
    dop853's steps are long: its refined states are stepped to, not interpolated (the message says)."""
    run = simulate({**PENDULUM, "integrator": integrator, "rtol": 1e-8, "atol": 1e-10}, progress=False)
    est = run.summary["error_estimate"]
    assert est["method"] == "tolerance / 10"
    assert est["refined"] == pytest.approx({"rtol": 1e-9, "atol": 1e-11, "every": 1})
    assert est["richardson"] is None and est["rows"] == run.t.size
    true = true_error(run)
    for k in STATES:
        assert 0.7 < est["max_abs"][k] / true[k] < 1.3, (k, est["max_abs"][k], true[k])
    assert ("stepped to" in est["message"]) == (integrator == "dop853"), est["message"]


def test_the_estimate_shrinks_by_2_to_the_order_when_dt_halves():
    """Kutta–Merson is of order 4: halving dt divides the estimate by ≈ 16 (17.5 measured)."""
    coarse, fine = (
        simulate({**PENDULUM, "dt": dt}, progress=False).summary["error_estimate"]["max_abs"] for dt in (0.01, 0.005)
    )
    for k in STATES:
        assert 12 < coarse[k] / fine[k] < 22, (k, coarse[k] / fine[k])


def test_a_refined_run_that_fails_is_reported_not_numbers(monkeypatch):
    """The refined adaptive run keeps every step; past the row cap it fails, and the estimate says
    so instead of giving numbers (the run itself, thinned by every = 10, is fine)."""
    monkeypatch.setitem(LIMITS, "max_rows", 1000)
    run = simulate({**PENDULUM, "integrator": "kutta-merson-adaptive", "rtol": 1e-8, "every": 10}, progress=False)
    est = run.summary["error_estimate"]
    assert run.status == "ok"
    assert est["refined_status"] == "failed" and est["max_abs"] is None and est["richardson"] is None
    assert est["message"].startswith("no estimate: the refined run (rtol = 1e-09, atol = 1e-13) ended failed: ")
    RunSummary.model_validate(run.summary)


def test_a_run_that_does_not_reach_its_end_gets_no_refined_run():
    run = simulate({**PENDULUM, "max_violation": 1e-14}, progress=False)  # the bar's round-off passes it
    est = run.summary["error_estimate"]
    assert run.status == "drifted" and est["refined_status"] is None and est["max_abs"] is None
    assert est["message"] == "no estimate: the run ended drifted (the estimate compares runs that reach their end)"


def test_a_refined_tolerance_below_rounding_is_said_in_words():
    run = simulate({**PENDULUM, "t_final": 1.0, "integrator": "kutta-merson-adaptive", "rtol": 1e-14}, progress=False)
    est = run.summary["error_estimate"]
    assert est["max_abs"] is None and est["refined_status"] is None and "below 100ε" in est["message"]


def test_a_refined_run_past_the_step_budget_is_refused_before_anything_runs(monkeypatch):
    monkeypatch.setitem(LIMITS, "max_steps", 1500)  # the run's 1,000 steps fit, dt/2's 2,000 do not
    plan = resolve(PENDULUM)
    with pytest.raises(InputError) as err:
        simulate(plan, progress=False)
    assert err.value.field == "error_estimate" and err.value.reason == "its second run at dt/2 would take 2,000 steps"
    assert "dt ≥ 0.0134 s" in err.value.allowed
    assert simulate({**PENDULUM, "error_estimate": False}, progress=False).status == "ok"


def test_both_runs_share_the_time_limit(monkeypatch):
    import nmkane_core.run.simulate as sim

    seen = []
    real = sim.add_error_estimate

    def spy(run, plan, rerun, **kw):
        seen.append(kw["time_left"])
        return real(run, plan, rerun, **kw)

    monkeypatch.setattr(sim, "add_error_estimate", spy)
    assert simulate(PENDULUM, progress=False, time_limit=30.0).summary["error_estimate"]["max_abs"]
    assert 0.0 < seen[0] < 30.0  # what the first run took is taken from the second's share
    # no time left: the refined run stops at once, and the estimate says so
    plan = resolve({**PENDULUM, "dt": 0.001})
    run = simulate(plan, progress=False)
    add_error_estimate(run, plan, simulate, time_left=0.0)
    est = run.summary["error_estimate"]
    assert est["refined_status"] == "timeout" and est["max_abs"] is None and "ended timeout" in est["message"]


def test_no_estimate_unless_asked():
    assert simulate({**PENDULUM, "error_estimate": False}, progress=False).summary["error_estimate"] is None


def test_interpolation_is_exact_for_polynomials_of_degree_7_and_at_the_rows():
    rng = np.random.default_rng(1)
    tr = np.cumsum(rng.uniform(0.5, 1.5, 40))
    coef = rng.normal(size=8)
    X = np.polyval(coef, tr)[:, None]
    t = np.sort(rng.uniform(tr[0], tr[-1], 200))
    assert np.allclose(interpolate(tr, X, t)[:, 0], np.polyval(coef, t), rtol=1e-9, atol=1e-9 * np.abs(X).max())
    assert np.array_equal(interpolate(tr, X, tr[[0, 7, 20, 39]]), X[[0, 7, 20, 39]])


def test_the_command_line_prints_the_estimate(capsys):
    from nmkane_core.cli import main

    assert main(["run", "iftomm-a01", "--t-final", "1", "--dt", "0.01", "--error-estimate", "--no-progress"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("error    "))
    assert "estimated global error, from a run at dt = 0.005 s; Richardson ×16/15" in line and " u2 " in line
