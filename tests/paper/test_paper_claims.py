"""The paper's claims (Bajodah, Hodges & Chen 2005), as computed for the report of
`nmkane figures` (issue 7); each claim is tested once, here.

The runs are those of the report in quick mode, made once per session (tests/conftest.py):
Fig. 18 over 100 s and Fig. 16's reference at Δt = 0.005 s; Figs. 11–15 and 17 over the
paper's full 500 s (Fig. 15's bound needs it, and at Δt = 0.001 s the undamped drift only
starts to grow after ≈ 120 s).  Each test checks the claim's status in the table *and* the
numbers behind it, so a wrong verdict in the report and a wrong number both fail.
"""

import pytest

import nmkane_core.paper.runs as paper_runs
from nmkane_core.paper import FAIL, NOT_RUN, PASS, collect_runs, evaluate_claims, run_plan
from nmkane_core.run.simulate import simulate


@pytest.fixture(scope="module")
def runs(quick_runs):
    return quick_runs


@pytest.fixture(scope="module")
def claims(runs):
    return {c.key: c for c in evaluate_claims(runs)}


def test_every_run_of_the_report_completes(runs):
    assert not runs.errors, runs.errors
    assert set(runs.results) == set(run_plan(quick=True))


# ---- Example 1 ----------------------------------------------------------------------
def test_constraint_models_give_the_same_motion_figs2_8(claims):
    c = claims["models_same_motion"]
    assert c.status == PASS, c.measured
    assert max(c.values["max_abs_diff"].values()) < 1e-6


def test_nonminimal_solution_matches_kanes_method_oracle_figs2_8(claims):
    c = claims["matches_kanes_method_oracle"]
    assert c.status == PASS, c.measured
    assert set(c.values["max_abs_diff"]) == {"theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5"}
    assert max(c.values["max_abs_diff"].values()) < 1e-6


def test_theta_reaches_steady_state_figs2_4_6(claims):
    c = claims["theta_reaches_steady_state"]
    assert c.status == PASS, c.measured
    assert abs(c.values["theta_dot_end"]) < 1e-6  # the claim allows 1e-3; measured ≈ 2e-12 rad/s
    assert 2.0 < c.values["theta_end"] < 2.5  # ≈ 2.2515 rad with the paper's initial state


def test_load_falls_and_spins_the_wheel_up_figs3_5_8(claims):
    c = claims["load_falls_wheel_speeds_up"]
    assert c.status == PASS, c.measured
    z0, z1 = c.values["z"]
    w0, w1 = c.values["phi_dot"]
    assert z0 == pytest.approx(30.0) and z1 < z0 and w1 > 5 * w0


def test_nonlinear_model_energy_drift_below_linear_fig9(claims, runs):
    c = claims["fig9_nonlinear_energy_drift_below_linear"]
    assert c.status == PASS, c.measured
    assert c.values["nonlinear"] < c.values["linear"]
    nl, lin = runs["ah-nonlinear"].settings, runs["ah-linear"].settings
    assert (nl["integrator"], nl["dt"], nl["t_final"]) == (lin["integrator"], lin["dt"], lin["t_final"])
    # not an accident of the report's Δt = 0.01 s over 20 s: the same at coarser steps and over 100 s
    for dt, t_final in ((0.01, 100), (0.05, 20), (0.05, 100), (0.1, 20), (0.1, 100)):
        drift = {}
        for model in ("nonlinear", "linear"):
            run = simulate(
                {
                    "system": "appell-hamel",
                    "model": model,
                    "dt": dt,
                    "t_final": t_final,
                    "integrator": "kutta-merson",
                    "every": 10,
                }
            )
            assert run.status == "ok"
            drift[model] = run.summary["max_abs_energy_drift"]
        assert drift["nonlinear"] < drift["linear"], (dt, t_final, drift)


# ---- Example 2: drift without stabilization ------------------------------------------
def test_undamped_particle_violation_grows_with_time_figs11_12(claims):
    c = claims["fig11_12_undamped_violation_grows"]
    assert c.status == PASS, c.measured
    for dt in (0.01, 0.001):
        v = c.values[dt]
        assert v["last_fifth"] > 3 * v["first_fifth"], (dt, v)


def test_undamped_particle_violation_smaller_at_smaller_step_figs11_12(claims):
    c = claims["fig11_12_smaller_step_smaller_violation"]
    assert c.status == PASS, c.measured
    assert c.values["dt0.001"] < c.values["dt0.01"] / 1e4


def test_undamped_particle_energy_drift_grows_with_time_figs13_14(claims):
    c = claims["fig13_14_undamped_energy_drift_grows"]
    assert c.status == PASS, c.measured


def test_undamped_particle_energy_drift_smaller_at_smaller_step_figs13_14(claims):
    c = claims["fig13_14_smaller_step_smaller_energy_drift"]
    assert c.status == PASS, c.measured
    assert c.values["dt0.001"] < c.values["dt0.01"] / 1e3


# ---- Fig. 15 (full horizon, also in quick mode) ----------------------------------------
def test_damped_particle_bound_matches_paper_fig15(claims, runs):
    run = runs["sp-damped-dt0.001"]
    assert run.settings["t_final"] == 500 and run.summary["steps"] == 500_000
    assert (run.settings["gamma1"], run.settings["gamma2"], run.settings["dt"]) == (-20, -100, 0.001)
    c = claims["fig15_damped_bound"]
    assert c.status == PASS, c.measured
    # paper: |φ| < 2.0e−11 m; an independent Kutta–Merson gives ≈ 1.8e−11 m
    assert 1.7e-11 < c.values["max_abs_phi"] < 2.0e-11
    assert c.values["second_half"] <= 1.5 * c.values["first_half"]  # bounded, not growing


# ---- Fig. 16 ---------------------------------------------------------------------------
def test_damped_nonminimal_stays_in_the_bowl_after_1h_fig16(claims):
    c = claims["fig16_damped_stays_in_bowl"]
    assert c.status == PASS, c.measured
    lo, hi = c.values["damped"]
    assert lo >= -0.1 and hi <= 1.1


def test_undamped_nonminimal_drifts_off_by_orders_of_magnitude_fig16(claims):
    c = claims["fig16_undamped_drifts_off"]
    assert c.status == PASS, c.measured
    assert c.values["orders"] >= 2


def test_damped_nonminimal_far_closer_to_fine_reference_than_undamped_fig16(claims, runs):
    c = claims["fig16_compared_with_fine_reference"]
    assert c.status == PASS, c.measured
    v = c.values
    assert v["DN"]["rms_last_10min"] < v["N"]["rms_last_10min"] / 100
    # the fine-step reference itself conserves energy to well under 1e-3 of E0
    ref = runs["sp-1h-reference"]
    assert ref.summary["max_abs_energy_drift"] < 1e-3 * ref.energy[0]


# ---- Fig. 17 vs 14 ---------------------------------------------------------------------
def test_damping_increases_energy_error_fig17_vs_fig14(claims):
    c = claims["fig17_damping_increases_energy_error"]
    assert c.status == PASS, c.measured
    assert c.values["damped"] > c.values["undamped"]


# ---- Fig. 18 ---------------------------------------------------------------------------
def test_baumgarte_blajer_and_yoon_all_keep_violation_bounded_fig18(claims):
    c = claims["fig18_all_bounded"]
    assert c.status == PASS, c.measured
    assert set(c.values) == {"Baumgarte", "Blajer", "Yoon et al."}


def test_fig18_projections_hold_violation_below_baumgarte_unlike_the_paper(claims):
    """Measured: the post-step corrections keep |φ| at round-off, far below Baumgarte's bound —
    the opposite of the paper's conclusion.  The report must say so plainly, with numbers."""
    c = claims["fig18_baumgarte_smallest_bound"]
    m = c.values["max_abs_phi"]
    assert m["Blajer"] < 1e-12 and m["Yoon et al."] < 1e-12
    assert 1e-8 < m["Baumgarte"] < 1e-6
    assert c.status == FAIL
    assert "DISAGREES" in c.measured
    for value in (m["Baumgarte"], m["Blajer"], m["Yoon et al."]):
        assert f"{value:.2e}" in c.measured
    # even one step before a correction the violation stays below Baumgarte's bound
    for pre in c.values["precorrection"].values():
        assert pre["samples"] >= 100 and pre["max"] < m["Baumgarte"]


def test_fig18_claims_not_run_when_the_library_refuses_a_projection(monkeypatch):
    plan = run_plan(quick=True)
    plan["sp-fig18-yoon"] = {**plan["sp-fig18-yoon"], "projection": "no-such-method"}
    monkeypatch.setattr(paper_runs, "run_plan", lambda quick=False: plan)
    keys = ["sp-fig18-baumgarte", "sp-fig18-blajer", "sp-fig18-yoon"]
    part = collect_runs(quick=True, progress=False, keys=keys)
    assert "sp-fig18-yoon" in part.errors and "projection" in part.errors["sp-fig18-yoon"]
    assert part.ok("sp-fig18-baumgarte") and part.ok("sp-fig18-blajer")
    claims = {c.key: c for c in evaluate_claims(part)}
    for key in ("fig18_all_bounded", "fig18_baumgarte_smallest_bound"):
        assert claims[key].status == NOT_RUN
        assert "sp-fig18-yoon" in claims[key].measured
    assert claims["fig15_damped_bound"].status == NOT_RUN  # not part of this subset


def test_claims_cover_every_figure_with_a_claim_in_the_issue(claims):
    covered = {f for c in claims.values() for f in c.figures}
    assert {9, 11, 12, 14, 15, 16, 17, 18} <= covered
    assert all(c.status in (PASS, FAIL) for c in claims.values()), [
        (c.key, c.status, c.measured) for c in claims.values() if c.status not in (PASS, FAIL)
    ]
