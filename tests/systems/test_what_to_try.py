"""Every teaching sentence is a test (issue 43): each claim a built-in system's "what to try"
paragraph makes about what a run shows is checked here, on the page's own defaults (the
settings the web page starts with: :func:`web.generic.generic_controls` read back by
:func:`web.controls.settings_from` — the system's defaults and showcase, Δt kept in the step
slider's range) plus the setting the sentence names.

Claims tested elsewhere on the same settings are not repeated: IFToMM A02's in
test_closed_loops_compiled.py; the Appell–Hamel motion and Fig. 9's energy errors (the page's
Δt = 0.01 s and 20 s are the paper's) in tests/paper/test_paper_claims.py; the rolling disk's
upright threshold in test_teaching_texts.py; the weave and capsize speeds in
test_bicycle_events_stability.py; A05's conserved angular momentum and decreasing energy in
test_iftomm.py (the page's run but for the rows it keeps)."""

from __future__ import annotations

import functools
import json
import math

import numpy as np
import pytest

from nmkane_core import simulate
from nmkane_core.errors import InputError
from nmkane_core.run.plan import default_projection, resolve
from nmkane_core.run.registry import get_system, system_names
from nmkane_core.systems import iftomm_a01
from web.controls import settings_from
from web.generic import generic_controls

TWO_PI = 2 * math.pi


@functools.cache
def _page_json(name: str) -> str:
    core = get_system(name)
    controls = {c: c.default for c in generic_controls(core, "what_to_try_")}
    settings, _ = settings_from(core, controls, lambda value: value)
    return json.dumps(settings, sort_keys=True)


def page(name: str, initial: dict | None = None, params: dict | None = None, **changes) -> dict:
    """The settings of the page's first run of ``name``, with the named changes."""
    s = {**json.loads(_page_json(name)), **changes}
    if initial:
        s["initial"] = {**s.get("initial", {}), **initial}
    if params:
        s["params"] = {**s.get("params", {}), **params}
    return s


@functools.cache
def _run(key: str):
    return simulate(json.loads(key), progress=False)


def run(name: str, ok: bool = True, **changes):
    """The page's run with the named changes (made once per module; ``ok``: it must complete)."""
    r = _run(json.dumps(page(name, **changes), sort_keys=True))
    if ok:
        assert r.summary["status"] == "ok", r.summary["message"]
    return r


def vmax(r, name: str, t0: float = -math.inf, t1: float = math.inf) -> float:
    """max |violation ``name``| over t0 ≤ t ≤ t1."""
    inside = (r.t >= t0) & (r.t <= t1)
    return float(np.abs(r.violation[name][inside]).max())


def circle(x, y) -> tuple[float, float, float, float]:
    """The least-squares circle through the points: centre, radius, largest distance off it."""
    a = np.column_stack([x, y, np.ones_like(x)])
    c = np.linalg.lstsq(a, x**2 + y**2, rcond=None)[0]
    cx, cy = c[0] / 2, c[1] / 2
    r = math.sqrt(c[2] + cx**2 + cy**2)
    return cx, cy, r, float(np.abs(np.hypot(x - cx, y - cy) - r).max())


def test_the_page_defaults_are_the_systems_own_but_for_the_slider_ranges_and_showcase():
    """The helper reads the page: A03's Δt = 1e-5 is below the step slider (the page starts at
    1e-4), A01 and the sliding particle start on their showcases."""
    assert get_system("iftomm-a03").default_dt == 1e-5 and page("iftomm-a03")["dt"] == 1e-4
    assert page("iftomm-a01")["t_final"] == 10.0 and page("appell-hamel")["dt"] == 0.01
    assert page("sliding-particle")["dt"] == 0.05 and page("sliding-particle")["gamma1"] == -20.0


# ---------------------------------------------------------------------------- Appell–Hamel
ROLLING = ("rolling_speed", "no_side_slip")


def test_appell_hamel_negative_gamma_lowers_the_late_violation_but_raises_the_early_maximum():
    """'Set Γ below 0: the rolling constraints' violations at the end of a run drop by orders of
    magnitude, but at Δt = 0.01 the largest, early in the run, grows with |Γ| (3× at Γ = −10, over
    100× at −50)'.  Measured: the largest 2.9e-10 (Γ = 0), 9.0e-10 (−10), 7.3e-8 (−50), at t ≈ 1 s;
    the end values fall from 2.9e-10 and 9.5e-11 to ≈ 1e-13 and ≈ 1e-14."""
    free = run("appell-hamel")
    largest = {}
    for gamma in (-10.0, -50.0):
        damped = run("appell-hamel", gamma=gamma)
        for name in ROLLING:
            assert abs(damped.violation[name][-1]) < 1e-2 * abs(free.violation[name][-1]), (gamma, name)
        largest[gamma] = max(damped.summary["max_abs_violation"][n] for n in ROLLING)
        t_at = damped.t[np.argmax(np.abs(damped.violation["rolling_speed"]))]
        assert t_at < 3.0, t_at  # early in the run
    ratio = {g: v / max(free.summary["max_abs_violation"][n] for n in ROLLING) for g, v in largest.items()}
    assert 2.0 < ratio[-10.0] < 5.0 and ratio[-50.0] > 100.0, ratio


def test_appell_hamel_a_smaller_step_brings_the_early_maximum_down():
    """'... a smaller step brings it down': at Γ = −50, 7.3e-8 at Δt = 0.01, 2e-11 at 0.002."""
    coarse = run("appell-hamel", gamma=-50.0).summary["max_abs_violation"]
    fine = run("appell-hamel", gamma=-50.0, dt=0.002).summary["max_abs_violation"]
    for name in ROLLING:
        assert fine[name] < 1e-2 * coarse[name], (name, fine[name], coarse[name])


def test_appell_hamel_a_wheel_not_rolling_switches_to_the_linear_model_and_back():
    """'Set u2 = φ̇ to 0: ... J2 is singular ..., and the run switches to the linear model (the
    status line says when)': at t = 0 to linear, back at t = 0.25 s once the wheel rolls."""
    r = run("appell-hamel", initial={"u2": 0.0})
    switches = r.summary["switches"]
    assert [(s["from"], s["to"]) for s in switches] == [("nonlinear", "linear"), ("linear", "nonlinear")]
    assert switches[0]["t"] == 0.0 and switches[0]["rcond"] < 1e-10 and 0.0 < switches[1]["t"] < 1.0


def test_appell_hamel_thread_tension_is_m_g_plus_z_ddot_below_m_g_while_the_load_speeds_up():
    r = run("appell-hamel")
    m, g = 1.0, 9.81
    tension = r.point_forces["thread.tension"]
    z_ddot = np.gradient(r.state["u5"], r.t)
    assert np.all(np.diff(np.abs(r.state["u5"])) > 0)  # the load speeds up throughout
    assert np.abs(tension - m * (g + z_ddot))[5:-5].max() < 1e-4  # (finite differences: 1.2e-6)
    assert tension.max() < m * g and tension.min() > 0.9 * m * g  # 9.24 … 9.53 N


def test_appell_hamel_both_models_give_the_same_forces_and_different_multipliers():
    """'Both models give the same forces ...; their multipliers differ (the nonlinear model's
    rolling_speed multiplier is a force divided by 2 a φ̇)': the longitudinal contact force."""
    nonlinear, linear = run("appell-hamel"), run("appell-hamel", model="linear")
    for name, f in nonlinear.point_forces.items():
        assert np.abs(f - linear.point_forces[name]).max() < 1e-7, name  # measured 1.5e-10
    assert set(nonlinear.multipliers) != set(linear.multipliers)
    a = 1.0
    times_2a_phidot = nonlinear.multipliers["rolling_speed"] * 2 * a * nonlinear.state["u2"]
    assert np.abs(times_2a_phidot - nonlinear.point_forces["contact.longitudinal"]).max() < 1e-7
    assert np.abs(nonlinear.point_forces["contact.longitudinal"]).max() > 0.1


# ------------------------------------------------------------------------ sliding particle
def test_sliding_particle_undamped_ghost_drifts_off_the_damped_run_stays_the_minimal_one_has_no_violation():
    """The page's Fig. 16 comparison (Δt = 0.05 s, 300 s): undamped (N) |φ| grows to 0.68 m, the
    damped run (DN) stays below 2.3e-4 m, the minimal solution (M) has no violation at all."""
    damped = run("sliding-particle")
    undamped = run("sliding-particle", gamma1=0.0, gamma2=0.0)
    minimal = run("sliding-particle", formulation="minimal")
    assert vmax(undamped, "surface") > 0.1 and vmax(damped, "surface") < 1e-3
    assert vmax(undamped, "surface", 240.0) > 5 * vmax(undamped, "surface", 0.0, 60.0)  # it drifts
    assert vmax(damped, "surface", 240.0) <= vmax(damped, "surface", 0.0, 60.0)  # it stays
    assert vmax(minimal, "surface") < 1e-12  # measured: exactly 0


def test_sliding_particle_a_smaller_step_shrinks_the_undamped_drift():
    drift = [vmax(run("sliding-particle", gamma1=0.0, gamma2=0.0, dt=dt), "surface") for dt in (0.05, 0.02, 0.01)]
    assert drift[0] > 10 * drift[1] > 100 * drift[2], drift  # 0.68, 4.0e-3, 6.5e-5


def test_sliding_particle_positive_gains_make_the_constraint_error_grow():
    """Γ1 = +1: the error grows until the run stops at its energy bound (t ≈ 28 s); without the
    bound it goes on growing, 1e20 times over the next 200 s."""
    grown = run("sliding-particle", ok=False, gamma1=1.0, gamma2=0.0)
    assert grown.summary["status"] == "drifted" and 20.0 < grown.t[-1] < 40.0, grown.summary["message"]
    free = run("sliding-particle", gamma1=0.0, gamma2=0.0)
    assert vmax(grown, "surface", 0.0, 20.0) > 1e3 * vmax(free, "surface")
    unbounded = run("sliding-particle", gamma1=1.0, gamma2=0.0, max_energy_drift=1e300)
    assert vmax(unbounded, "surface", 240.0) > 1e20 * vmax(unbounded, "surface", 0.0, 60.0)


# ------------------------------------------------------------------------------ knife edge
def test_knife_edge_a_zero_turning_rate_runs_straight():
    r = run("knife-edge", initial={"u3": 0.0})
    assert np.ptp(r.state["theta"]) == 0.0 and np.abs(r.state["y"]).max() < 1e-12
    assert r.state["x"][-1] == pytest.approx(20.0)


@pytest.mark.parametrize("u1, u3", [(1.0, 0.5), (2.0, 0.5), (1.0, 1.0), (2.0, -1.0)])
def test_knife_edge_draws_a_circle_of_radius_u1_over_u3(u1, u3):
    r = run("knife-edge", initial={"u1": u1, "u3": u3})
    _, _, radius, off = circle(r.state["x"], r.state["y"])
    assert radius == pytest.approx(abs(u1 / u3), rel=1e-9) and off < 1e-9


@pytest.mark.parametrize("u1", [1.0, 2.0])
def test_knife_edge_blade_force_points_to_the_centre_and_is_m_v_omega(u1):
    """0.5 N by default (m = 1, v = 1, ω = 0.5); double u1 and it doubles."""
    r = run("knife-edge", initial={"u1": u1})
    force = r.point_forces["blade.lateral"]
    assert force == pytest.approx(np.full_like(force, 0.5 * u1), rel=1e-9)
    cx, cy, _, _ = circle(r.state["x"], r.state["y"])
    th = r.state["theta"]
    sideways_to_centre = -np.sin(th) * (cx - r.state["x"]) + np.cos(th) * (cy - r.state["y"])
    assert np.all(force * sideways_to_centre > 0)  # along the blade's sideways axis, to the centre


def test_knife_edge_blade_force_does_no_work_the_energy_drift_stays_at_round_off():
    for initial in ({}, {"u1": 2.0}, {"u3": -1.0}):
        assert run("knife-edge", initial=initial).summary["max_abs_energy_drift"] < 1e-13


# ------------------------------------------------------------------------ Chaplygin sleigh
def _sleigh(a: float):
    r = run("chaplygin-sleigh", params={"a": a})
    m, inertia = 1.0, 0.1
    u1, u3 = r.state["u1"], r.state["u3"]
    energy = (m * u1[0] ** 2 + (inertia + m * a * a) * u3[0] ** 2) / 2
    return r, math.sqrt(2 * energy / m)


def test_chaplygin_sleigh_spin_dies_away_and_it_slides_straight_ahead_at_sqrt_2e_over_m():
    r, speed = _sleigh(0.5)
    assert abs(r.state["u3"][-1]) < 1e-6 * abs(r.state["u3"][0])
    assert r.state["u1"][-1] == pytest.approx(speed, rel=1e-6)  # 1.1874 m/s from u1 = 0.1
    assert r.summary["max_abs_energy_drift"] < 1e-8


def test_chaplygin_sleigh_mass_centre_behind_the_blade_slides_away_backwards():
    r, speed = _sleigh(-0.5)
    assert abs(r.state["u3"][-1]) < 1e-6 and r.state["u1"][-1] == pytest.approx(-speed, rel=1e-6)


def test_chaplygin_sleigh_with_a_zero_is_a_knife_edge_turning_for_ever():
    r, _ = _sleigh(0.0)
    assert np.ptp(r.state["u3"]) < 1e-12 and np.ptp(r.state["u1"]) < 1e-12


def test_chaplygin_sleigh_blade_force_is_below_the_point_mass_one_and_fades_with_the_spin():
    """blade.lateral = m v ω I/(I + m a²) (0.34 N at most by default, m v ω then 1.19 N)."""
    a, m, inertia = 0.5, 1.0, 0.1
    r, _ = _sleigh(a)
    force, m_v_omega = r.point_forces["blade.lateral"], m * r.state["u1"] * r.state["u3"]
    assert np.abs(force - m_v_omega * inertia / (inertia + m * a * a)).max() < 1e-9
    assert np.all(np.abs(force) <= np.abs(m_v_omega)) and np.abs(force).max() < 0.5 * np.abs(m_v_omega).max()
    assert abs(force[-1]) < 1e-6 * np.abs(force).max()


# ---------------------------------------------------------------------------- rolling disk
def test_rolling_disk_leaning_with_a_yaw_rate_turns_on_a_circle():
    """The page starts leaning (θ = 0.2) with u3 = −1.5: the coin wobbles (θ between 0.02 and 0.2)
    and its contact point runs along a circle of 4.2 m (within 1 %), two thirds of a lap in 10 s."""
    r = run("rolling-disk")
    _, _, radius, off = circle(r.state["x"], r.state["y"])
    assert 3.0 < radius < 6.0 and off < 0.02 * radius
    assert abs(r.state["psi"][-1] - r.state["psi"][0]) > 0.5 * TWO_PI


def test_rolling_disk_does_not_slip_its_violation_is_the_integrators_error_and_no_energy_is_lost():
    """'its violation, below 1e-9 m/s, is the integrator's error: halve Δt and it falls 16-fold':
    3.0e-10 → 1.9e-11 m/s; ΔE 8.7e-10 J of 5.1 J."""
    r, half = run("rolling-disk"), run("rolling-disk", dt=page("rolling-disk")["dt"] / 2)
    for name, v in r.summary["max_abs_violation"].items():
        assert v < 1e-9 and 10 < v / half.summary["max_abs_violation"][name] < 25, name
    assert r.summary["max_abs_energy_drift"] < 1e-8


def test_rolling_disk_friction_points_to_the_centre_and_the_normal_force_is_m_g_only_upright_and_straight():
    m_g = 9.81
    r = run("rolling-disk")
    cx, cy, _, _ = circle(r.state["x"], r.state["y"])
    psi = r.state["psi"]
    sideways_to_centre = -np.sin(psi) * (cx - r.state["x"]) + np.cos(psi) * (cy - r.state["y"])
    assert np.all(r.point_forces["contact.lateral"] * sideways_to_centre > 0)
    normal = r.point_forces["contact.normal"]
    assert normal.min() < m_g - 0.1 and normal.max() > m_g + 0.1  # 9.65 … 10.10 N as it wobbles
    straight = run("rolling-disk", initial={"theta": 0.0, "u3": 0.0, "u4": 0.0})
    assert np.abs(straight.point_forces["contact.normal"] - m_g).max() < 1e-12
    assert np.abs(straight.point_forces["contact.lateral"]).max() < 1e-12


# --------------------------------------------------------------------------- odometer puck
def _apsides(r):
    """Directions (rad) of the successive farthest points of the orbit, and its nearest radii."""
    x, y = r.state["x"], r.state["y"]
    rr = np.hypot(x, y)
    far = np.where((rr[1:-1] > rr[:-2]) & (rr[1:-1] >= rr[2:]))[0] + 1
    near = np.where((rr[1:-1] < rr[:-2]) & (rr[1:-1] <= rr[2:]))[0] + 1
    return np.arctan2(y[far], x[far]), rr[near]


def test_odometer_puck_with_j_zero_the_orbit_is_a_fixed_ellipse():
    r = run("odometer-puck", params={"J": 0.0})
    x, y = r.state["x"], r.state["y"]
    assert np.abs(x**2 + (y / 0.8) ** 2 - 1).max() < 1e-9  # x = cos t, y = 0.8 sin t


def test_odometer_puck_raising_j_precesses_the_orbit_and_changes_its_shape_at_constant_energy():
    """At the page's J = 0.02 the farthest point turns by 140° per half orbit (0° with J = 0) and
    the nearest approach is 0.71 m instead of 0.8 m; ΔE 1.5e-12 J."""
    for J in (0.02, 0.1):
        r = run("odometer-puck", params={"J": J})
        far, near = _apsides(r)
        turned = np.abs(np.angle(np.exp(1j * (np.diff(far) - math.pi))))
        assert len(far) > 4 and turned.min() > 0.5, (J, turned)
        assert np.all(near < 0.75), (J, near)
        assert r.summary["max_abs_energy_drift"] < 1e-9


def test_odometer_puck_speeds_near_zero_blow_the_gradient_up_a_good_push_runs():
    assert run("odometer-puck", ok=False, initial={"u2": 0.0}).summary["status"] != "ok"
    weak = run("odometer-puck", initial={"u2": 1e-3}).summary
    pushed = run("odometer-puck").summary
    assert weak["max_abs_violation"]["odometer"] > 1e6 * pushed["max_abs_violation"]["odometer"]


def test_odometer_puck_wheel_force_brakes_as_the_flywheel_speeds_up_and_pushes_as_it_slows():
    r = run("odometer-puck")
    force, spin_up = r.point_forces["wheel.tangential"], np.gradient(r.state["u3"], r.t)
    clear = np.abs(spin_up) > 1e-3 * np.abs(spin_up).max()
    clear[[0, -1]] = False  # one-sided differences (and at t = 0 the spring is across the path)
    assert np.all(np.sign(force[clear]) == -np.sign(spin_up[clear]))
    assert np.abs(force).max() > 0.1 and r.summary["max_abs_energy_drift"] < 1e-9


# ------------------------------------------------------------------------- Whipple bicycle
def test_whipple_bicycle_at_5_m_per_s_a_roll_push_dies_out():
    r = run("whipple-bicycle", initial={"u4": 0.5})  # the page starts at 5 m/s (u6 = −16.7)
    q4 = np.abs(r.state["q4"])
    assert r.summary["event"] is None and q4[-1] < 0.1 * q4.max()  # 0.105 → 0.006 rad in 5 s


def test_whipple_bicycle_at_3_m_per_s_the_same_push_makes_it_fall_and_the_run_stops():
    r = run("whipple-bicycle", ok=False, initial={"u6": -10.0, "u4": 0.5})
    assert r.summary["status"] == "event" and r.summary["event"]["name"] == "handlebar_touches_ground"
    assert r.t[-1] < page("whipple-bicycle")["t_final"]  # at 1.95 s


def test_whipple_bicycle_above_6_m_per_s_it_capsizes_slowly():
    r = run("whipple-bicycle", initial={"u6": -25.0, "u4": 0.5})
    q4, t = r.state["q4"], r.t
    assert r.summary["event"] is None
    assert abs(q4[-1]) > 1.2 * abs(q4[np.searchsorted(t, 2.0)]) > 0.02  # 0.041 at 2 s, 0.060 at 5 s
    assert abs(q4[-1]) < 0.2  # slowly


# ------------------------------------------------------------------------------ IFToMM A01
def test_iftomm_a01_at_the_page_step_the_bar_keeps_its_length_with_or_without_gains():
    """Over the page's 10 s at Δt = 1e-3: 4.3e-12 m² with Γ1 = −20, Γ2 = −100, 7.1e-12 without."""
    for gains in ({}, {"gamma1": 0.0, "gamma2": 0.0}):
        assert vmax(run("iftomm-a01", **gains), "bar") < 5e-11, gains


def test_iftomm_a01_at_a_larger_step_the_bar_shortens_without_gains_and_holds_with_them():
    """Δt = 0.05: without gains x² + y² − L² never exceeds 0 and falls to −1.5e-4 m² at 10 s, three
    times its first 2 s; with them it stays within 5.4e-5 m², no larger at the end."""
    free = run("iftomm-a01", dt=0.05, gamma1=0.0, gamma2=0.0)
    v = free.violation["bar"]
    assert v.max() < 1e-12 and -2e-4 < v[-1] < -1e-4
    assert vmax(free, "bar", 8.0) > 2 * vmax(free, "bar", 0.0, 2.0)
    assert v[free.t >= 9.0].min() < v[(free.t >= 8.0) & (free.t < 9.0)].min()  # still falling
    held = run("iftomm-a01", dt=0.05)
    assert vmax(held, "bar") < 6e-5 and vmax(held, "bar", 8.0) < 1.2 * vmax(held, "bar", 0.0, 2.0)


def test_iftomm_a01_cartesian_y_switches_to_cartesian_at_the_horizontal_start_and_back():
    r = run("iftomm-a01", model="cartesian-y")
    switches = [(s["t"], s["from"], s["to"]) for s in r.summary["switches"]]
    assert switches == [(0.0, "cartesian-y", "cartesian"), (pytest.approx(0.025), "cartesian", "cartesian-y")]


def test_iftomm_a01_cartesian_passes_where_the_bar_hangs_down_without_switching_on_the_exact_motion():
    r = run("iftomm-a01")
    assert r.summary["switches"] == []
    assert np.count_nonzero(np.diff(np.sign(r.state["x"]))) >= 4  # it hangs down again and again
    assert iftomm_a01.acceptance(r.t, r.state["x"], r.state["y"])["P1_position"] < 1e-8  # 1.8e-10 m


# ------------------------------------------------------------------------------ IFToMM A03
def test_iftomm_a03_the_crank_turns_two_and_a_half_times_in_0_03_s():
    beta = run("iftomm-a03").state["beta"]
    assert (beta[-1] - beta[0]) / TWO_PI == pytest.approx(2.5, abs=0.05)


def test_iftomm_a03_delta_u_is_2_5e_6_at_the_page_step_grows_with_larger_steps_and_blows_up_at_2e_3():
    drift = {dt: run("iftomm-a03", dt=dt).summary["max_abs_energy_drift"] for dt in (1e-4, 5e-4)}
    assert 1e-6 < drift[1e-4] < 5e-6 and 5e-4 < drift[5e-4] < 3e-3, drift  # 2.5e-6, 1.4e-3 J
    assert run("iftomm-a03", ok=False, dt=2e-3).summary["status"] != "ok"


def test_iftomm_a03_without_the_motor_nothing_moves_until_beta_is_nudged():
    still = run("iftomm-a03", params={"mom": 0.0})
    assert max(np.ptp(v) for v in still.state.values()) < 1e-12
    beta0 = page("iftomm-a03")["initial"]["beta"]
    for nudge in (0.01, -0.01):
        beta = run("iftomm-a03", params={"mom": 0.0}, initial={"beta": beta0 + nudge}).state["beta"]
        assert abs(beta[-1] - beta[0]) > 0.9 * TWO_PI and np.sign(beta[-1] - beta[0]) == np.sign(nudge)


def test_iftomm_a03_a_softer_spring_slows_the_squeezing():
    beta, soft = run("iftomm-a03").state["beta"], run("iftomm-a03", params={"c0": 100.0}).state["beta"]
    assert soft[-1] - soft[0] < 0.5 * (beta[-1] - beta[0])  # 0.92 turns instead of 2.53


# ------------------------------------------------------------------------------ IFToMM A04
def test_iftomm_a04_paper_solve_is_refused_and_the_robust_solve_keeps_four_of_five_equations():
    with pytest.raises(InputError, match="rank 4"):
        simulate(page("iftomm-a04", solve="paper"), progress=False)
    r = run("iftomm-a04")
    assert len(r.violation) == 5 and r.summary["robust_solve"]["min_rank"] == 4


def test_iftomm_a04_released_from_rest_it_swings_for_ever_the_energy_drift_is_the_solvers():
    r = run("iftomm-a04")
    assert np.ptp(r.state["q1"]) == pytest.approx(math.pi, abs=1e-6)
    assert np.count_nonzero(np.diff(np.sign(r.state["u1"]))) >= 4  # back and forth, on and on
    assert r.summary["max_abs_energy_drift"] < 1e-10  # 7.6e-13 J


def test_iftomm_a04_a_hard_push_runs_on_the_motion_of_a_ten_times_finer_step():
    hard = run("iftomm-a04", initial={"u1": 5.0})
    fine = run("iftomm-a04", initial={"u1": 5.0}, dt=page("iftomm-a04")["dt"] / 10)
    at = np.searchsorted(fine.t, hard.t - 1e-12)
    assert np.abs(fine.t[at] - hard.t).max() < 1e-9
    for q in ("q1", "q2", "q3", "q4", "q5"):
        assert np.abs(hard.state[q] - fine.state[q][at]).max() < 1e-7, q  # 7e-9 rad over the 10 s


# ------------------------------------------------------------------------------ IFToMM A05
def _stretch(r):
    """The springs' stretch (m): from the slider's point to the rod's midpoint (rest length 0.5 m)."""
    b, s = r.state["b1"], r.state["s"]
    return np.hypot(0.5 * np.cos(b), 1.0 - 0.5 * np.sin(b) - s) - 0.5


def test_iftomm_a05_dt_5e_4_blows_up_and_1e_4_runs():
    assert page("iftomm-a05")["dt"] == 1e-4 and run("iftomm-a05").t[-1] == pytest.approx(10.0)
    assert run("iftomm-a05", ok=False, dt=5e-4).summary["status"] in ("diverged", "drifted")


def test_iftomm_a05_a_faster_shaft_flings_the_balls_out_and_lifts_the_slider():
    slow, fast = run("iftomm-a05"), run("iftomm-a05", initial={"dphi": 10.0})
    assert fast.state["s"].mean() > slow.state["s"].mean() + 0.1  # 0.85 m against 0.63 m
    assert fast.state["b1"].mean() < slow.state["b1"].mean() - 0.1  # the rods nearer horizontal


def test_iftomm_a05_softer_springs_stretch():
    stiff, soft = run("iftomm-a05"), run("iftomm-a05", params={"k": 1e3})
    assert np.abs(_stretch(soft)).max() > 50 * np.abs(_stretch(stiff)).max()  # 8 mm against 0.06 mm


def test_the_page_starts_with_each_systems_declared_projection():
    """A02's paragraph speaks of its defaults' projection: the page's chooser starts at the
    system's ``default_projection`` (it started at "none" whatever the system declared), with
    ``auto`` resolved as runs resolve it (yoon for redundant constraint equations)."""
    for name in system_names():
        core = get_system(name)
        chosen = {c.field: c.default for c in generic_controls(core, "p_")}.get("projection")
        assert chosen == default_projection(core, core.default_variant) == resolve({"system": name}).projection.name
        assert chosen in ("none", "yoon"), name


def test_every_systems_default_gains_lie_on_the_pages_gain_sliders():
    """The page starts at each system's own gains; each lies inside its slider's range, so a
    teacher can type it back (A03's Γ1 = −2000, Γ2 = −1e6 lay outside −50…10 and −500…50)."""
    for name in system_names():
        core = get_system(name)
        for c in generic_controls(core, "g_"):
            if c.field in ("gamma", "gamma1", "gamma2"):
                assert c.min <= c.default <= c.max, (name, c.field, c.default, c.min, c.max)
