"""The catalogue of classic nonholonomic systems against independent references:
closed forms (knife edge, Chaplygin sleigh), a hand Newton–Euler steady-turning relation
and the v² = g r/3 stability limit (rolling disk), intrinsic equations integrated by scipy
(odometer puck); and their declared visuals compiled into pose functions."""

import math

import numpy as np
import pytest

from nmkane_core import get_system, simulate
from nmkane_core.kernel.visuals import compile_visuals, rotation_to_wxyz

CATALOGUE = ("knife-edge", "chaplygin-sleigh", "rolling-disk", "odometer-puck")


def run(name, **kw):
    r = simulate({"system": name, "integrator": "rk4", **kw}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    return r


def test_knife_edge_runs_on_the_closed_form_circle():
    v, w, th0 = 1.3, 0.7, 0.4
    r = run("knife-edge", dt=0.005, t_final=12.0, initial={"x": 0.5, "y": -1.0, "theta": th0, "u1": v, "u3": w})
    t = r.t
    x = 0.5 + v / w * (np.sin(th0 + w * t) - np.sin(th0))
    y = -1.0 - v / w * (np.cos(th0 + w * t) - np.cos(th0))
    assert np.max(np.abs(r.state["x"] - x)) < 1e-8
    assert np.max(np.abs(r.state["y"] - y)) < 1e-8
    assert np.max(np.abs(r.state["theta"] - (th0 + w * t))) < 1e-10
    assert r.summary["max_abs_energy_drift"] < 1e-10


@pytest.mark.parametrize("a,v0,w0", [(0.5, 0.1, 2.0), (0.8, -0.3, -1.0)])
def test_chaplygin_sleigh_speed_and_yaw_rate_in_closed_form(a, v0, w0):
    m, I = 1.5, 0.2
    r = run(
        "chaplygin-sleigh",
        dt=0.002,
        t_final=15.0,
        params={"m": m, "I": I, "a": a},
        initial={"x": 0, "y": 0, "theta": 0, "u1": v0, "u3": w0},
    )
    J = I + m * a * a
    E = (m * v0**2 + J * w0**2) / 2
    V = math.sqrt(2 * E / m)
    s = m * a * V / J * r.t + math.atanh(v0 / V)
    assert np.max(np.abs(r.state["u1"] - V * np.tanh(s))) < 1e-8
    assert np.max(np.abs(r.state["u3"] - np.sign(w0) * math.sqrt(m / J) * V / np.cosh(s))) < 1e-8
    assert r.summary["max_abs_energy_drift"] < 1e-9 * E
    assert r.state["u1"][-1] > 0.99 * V  # spin converted into forward motion


def test_rolling_disk_steady_turning_relation():
    m, rad, g = 1.0, 0.3, 9.81
    I1, I3 = m * rad**2 / 4, m * rad**2 / 2
    th, Om = 0.3, -2.0
    # I1 Ω² sinθ cosθ − (I3 + m r²) s Ω cosθ = m g r sinθ  (Newton–Euler about the centre, by hand)
    s = (I1 * Om**2 * math.sin(th) * math.cos(th) - m * g * rad * math.sin(th)) / (
        (I3 + m * rad**2) * Om * math.cos(th)
    )
    r = run(
        "rolling-disk",
        dt=0.002,
        t_final=5.0,
        params={"m": m, "r": rad, "g": g},
        initial={"x": 0, "y": 0, "psi": 0, "theta": th, "phi": 0, "u3": Om, "u4": 0, "u5": s - Om * math.sin(th)},
    )
    assert np.max(np.abs(r.state["theta"] - th)) < 1e-7
    assert np.max(np.abs(r.state["u3"] - Om)) < 1e-7
    # the contact point runs on a circle at the speed r·φ̇ (the centre's is r·s)
    speed = np.hypot(r.state["u1"], r.state["u2"])
    assert np.max(np.abs(speed - abs(rad * (s - Om * math.sin(th))))) < 1e-6
    assert r.summary["max_abs_energy_drift"] < 1e-9
    assert max(r.summary["max_abs_violation"].values()) < 1e-9  # the contact point does not slip


@pytest.mark.parametrize("factor,stable", [(1.25, True), (0.75, False)])
def test_upright_rolling_disk_is_stable_above_v2_equal_gr_over_3(factor, stable):
    rad, g = 0.3, 9.81
    v = math.sqrt(factor * g * rad / 3)
    r = run(
        "rolling-disk",
        dt=0.002,
        t_final=8.0,
        params={"r": rad, "g": g},
        initial={"x": 0, "y": 0, "psi": 0, "theta": 0.0, "phi": 0, "u3": 0, "u4": 0.01, "u5": v / rad},
    )
    lean = np.max(np.abs(r.state["theta"]))
    if stable:
        assert lean < 0.05, lean
    else:
        assert lean > 0.3, lean
    assert r.summary["max_abs_energy_drift"] < 1e-8
    assert max(r.summary["max_abs_violation"].values()) < 1e-9


def test_odometer_puck_matches_the_intrinsic_equations_and_keeps_energy():
    from scipy.integrate import solve_ivp

    m, J, rho, k = 1.0, 0.05, 0.1, 2.0
    mt = m + J / rho**2  # heavier along the path than across it
    r = run(
        "odometer-puck",
        dt=0.002,
        t_final=8.0,
        params={"m": m, "J": J, "rho": rho, "k": k},
        initial={"x": 1.0, "y": 0.0, "s": 0.0, "u1": 0.2, "u2": 0.9},
    )

    def rhs(_t, z):
        x, y, vx, vy = z
        sp = math.hypot(vx, vy)
        tx, ty = vx / sp, vy / sp
        fx, fy = -k * x, -k * y
        ft = fx * tx + fy * ty
        fnx, fny = fx - ft * tx, fy - ft * ty
        return [vx, vy, ft / mt * tx + fnx / m, ft / mt * ty + fny / m]

    ref = solve_ivp(rhs, (0, 8.0), [1.0, 0.0, 0.2, 0.9], t_eval=r.t, rtol=1e-11, atol=1e-12)
    assert np.max(np.abs(r.state["x"] - ref.y[0])) < 1e-6
    assert np.max(np.abs(r.state["y"] - ref.y[1])) < 1e-6
    assert np.max(np.abs(r.state["u3"] - np.hypot(r.state["u1"], r.state["u2"]) / rho)) < 1e-9
    assert r.summary["max_abs_energy_drift"] < 1e-8


@pytest.mark.parametrize("name", CATALOGUE)
def test_catalogue_systems_declare_visuals_that_compile_to_pose_functions(name):
    system = get_system(name)
    assert system.what_to_try and system.visuals is not None
    for p in system.parameters:
        assert math.isfinite(p.min) and math.isfinite(p.max), p  # a slider range for every parameter
    cv = compile_visuals(system)
    r = simulate({"system": name, "t_final": 1.0}, progress=False)
    frames, _ = cv.frame_poses(r.state, r.settings["params"])
    assert frames
    for pos, rot in frames.values():
        assert pos.shape == (len(r.t), 3) and np.all(np.isfinite(pos))
        np.testing.assert_allclose(rot @ np.swapaxes(rot, 1, 2), np.broadcast_to(np.eye(3), rot.shape), atol=1e-12)
    kinds = {s.kind for s in cv.shapes}
    assert "ground" in kinds and "trace" in kinds
    assert np.all(np.isfinite(cv.sizes(r.settings["params"])))


def test_rolling_disk_visual_centre_sits_r_above_the_contact_point():
    r = simulate({"system": "rolling-disk", "t_final": 2.0}, progress=False)
    p = r.settings["params"]
    frames, _ = compile_visuals(get_system("rolling-disk")).frame_poses(r.state, p)
    pos, rot = frames["disk"]
    contact = np.column_stack([r.state["x"], r.state["y"], np.zeros(len(r.t))])
    np.testing.assert_allclose(np.linalg.norm(pos - contact, axis=1), p["r"], rtol=1e-12)
    np.testing.assert_allclose(pos[:, 2], p["r"] * np.cos(r.state["theta"]), atol=1e-12)
    # the disk's axle (body y) is horizontal when upright at yaw ψ: (−sin ψ, cos ψ, 0) rotated by the lean
    axle = rot[:, :, 1]
    np.testing.assert_allclose(axle[:, 2], np.sin(r.state["theta"]), atol=1e-12)


def test_rotation_to_quaternion_round_trip():
    rng = np.random.default_rng(1)
    q = rng.normal(size=(200, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    R = np.stack(
        [
            1 - 2 * (y * y + z * z),
            2 * (x * y - w * z),
            2 * (x * z + w * y),
            2 * (x * y + w * z),
            1 - 2 * (x * x + z * z),
            2 * (y * z - w * x),
            2 * (x * z - w * y),
            2 * (y * z + w * x),
            1 - 2 * (x * x + y * y),
        ],
        axis=1,
    ).reshape(-1, 3, 3)
    back = rotation_to_wxyz(R)
    np.testing.assert_allclose(np.abs(np.sum(back * q, axis=1)), 1.0, atol=1e-12)
