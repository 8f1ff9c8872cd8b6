"""The web app in-process (no browser): controls re-simulate with their settings, the scene
nodes sit where the state puts them, plots and panel show the run.  The paper's two systems
go through the same generic page as every other (declared visuals, compare ghosts)."""

import math
import time

import numpy as np
import pytest

from nmkane_core.systems.appell_hamel import LOAD_RADIUS
from web import geometry as geo
from web import matrices as mx
from web import plots as pl
from web.app import MechanismApp, launch
from web.worker import LatestWorker

AH, PT = "appell-hamel", "sliding-particle"


@pytest.fixture()
def app(server):
    a = MechanismApp(server, sync=True)
    assert a.kind == AH  # the first registered system opens first
    yield a
    a.close()


def choose(app, name):
    app.scene_choice.value = next(t for t, n in app.choices.items() if n == name)
    assert app.kind == name and app.traj.kind == name


def node(app, path):
    return app.scene.get_handle_by_name(f"/sys/{app.kind}/{path}")


def wheel_centre(p, th, x, y):
    """o = (x − ρ cos θ, y − ρ sin θ, a), eqs. (53)–(54) integrated."""
    return np.array([x - p["rho"] * math.cos(th), y - p["rho"] * math.sin(th), p["a"]])


def test_slider_changes_resimulate_with_those_settings(app):
    app.control("gamma").value = -7.5
    app.control("gamma1").value = -20.0
    app.control("gamma2").value = -100.0
    app.control("variant").value = "linear"
    app.control("integrator").value = "rk4"
    app.control("dt").value = 0.0032
    app.control("t_final").value = 12.0
    last = app.sim_log[-1]
    assert (last["gamma"], last["gamma1"], last["gamma2"], last["model"], last["integrator"]) == (
        -7.5,
        -20.0,
        -100.0,
        "linear",
        "rk4",
    )
    assert last["dt"] == 0.0032 and last["t_final"] == 12.0
    run = app.traj.main  # the trajectory shown is the one just computed
    assert run.settings["model"] == "linear" and run.settings["gamma"] == -7.5
    assert run.settings["gamma1"] == -20.0 and run.settings["integrator"] == "rk4"
    assert run.t[-1] == pytest.approx(12.0)
    assert app.time.max == pytest.approx(12.0)


def test_typed_values_reach_the_run_exactly_and_bad_ones_are_refused_beside_the_box(app):
    """The teacher's item 1: what is typed is what the run uses, in the quantity's own units."""
    for field, text, value in (
        ("dt", "1e-3", 0.001),
        ("gamma", "-1e1", -10.0),
        ("t_final", "2.5E+1", 25.0),
        ("initial.u1", "5e-1", 0.5),
        ("params.M", "1e1", 10.0),  # a log slider: typed in kg
        ("initial.u2", "0.001", 0.001),
    ):
        app.control(field).text.value = text
        s = app.sim_log[-1]
        got = s[field] if "." not in field else s[field.split(".")[0]][field.split(".")[1]]
        assert got == value, (field, text, got)
        assert not app.control(field).message.visible
    runs = len(app.sim_log)
    for field, text, why in (
        ("initial.u1", "1,5", "decimal point as a point"),
        ("gamma", "1e9", "outside the allowed range -50 … 10"),
        ("t_final", "abc", "is not a number"),
        ("t_final", "1e6", "outside the allowed range 1 … 100 s"),
    ):
        h = app.control(field)
        before = h.value
        h.text.value = text
        assert h.value == before and h.message.visible and why in h.message.content, h.message.content
        assert why in app.status.content and "input refused" in app.status.content
    assert len(app.sim_log) == runs  # nothing ran with a refused value
    app.control("t_final").text.value = "7"  # good again: its message and its status line go
    assert app.sim_log[-1]["t_final"] == 7.0 and not app.control("t_final").message.visible
    assert "is not a number" not in app.status.content and "1e6" not in app.status.content
    assert "decimal point" in app.status.content  # the box still refused keeps its line


def test_physical_parameters_reach_the_run_and_reshape_the_scene(app):
    app.control("params.rho").value = 8.0
    app.control("params.a").value = 1.5
    p = app.traj.main.settings["params"]
    assert p["rho"] == pytest.approx(8.0) and p["a"] == pytest.approx(1.5)
    app.seek(0.0)
    run = app.traj.main
    th, x, y = (float(run.state[n][0]) for n in ("theta", "x", "y"))
    np.testing.assert_allclose(node(app, "frames/wheel").position, wheel_centre(p, th, x, y), atol=1e-6)
    disk = node(app, "frames/wheel/disk").vertices  # a round rim's mesh (web.geometry.disk_mesh)
    assert np.linalg.norm(disk, axis=1).max() == pytest.approx(1.5, rel=1e-6)


def test_initial_speed_sliders_complete_the_dependent_speeds(app):
    app.control("initial.u1").value = 0.5
    app.control("initial.u2").value = -1.0
    st = app.traj.main.state
    assert st["u1"][0] == 0.5 and st["u2"][0] == -1.0
    # completed by the library: (51)–(54) at θ = 0 give ẋ = aφ̇, ẏ = ρθ̇; (59) gives ż = −bφ̇
    assert st["u3"][0] == pytest.approx(-1.0) and st["u4"][0] == pytest.approx(2.5)
    assert st["u5"][0] == pytest.approx(0.5)


def test_scene_nodes_match_the_state_at_time_t(app):
    """The declared visuals, compiled and posed, put the parts where the paper's kinematics do."""
    run, p = app.traj.main, app.traj.params
    wheel, load, thread = node(app, "frames/wheel"), node(app, "world/load"), node(app, "world/thread")
    for t in (0.0, 3.3, 12.0, 19.99):
        app.seek(t)
        k = geo.index_at(run.t, t)
        th, ph, x, y, z = (float(run.state[n][k]) for n in ("theta", "phi", "x", "y", "z"))
        # (viser keeps poses in float32: 1 mm at 100 m from the origin is its resolution)
        np.testing.assert_allclose(wheel.position, wheel_centre(p, th, x, y), atol=1e-3)
        # wheel orientation: axle along (−sin θ, cos θ, 0); a wheel-fixed radius turned by φ
        rot = tuple(wheel.wxyz)
        np.testing.assert_allclose(geo.rotate(rot, (0, 1, 0)), (-math.sin(th), math.cos(th), 0), atol=2e-5)
        np.testing.assert_allclose(
            geo.rotate(rot, (1, 0, 0)),
            (math.cos(ph) * math.cos(th), math.cos(ph) * math.sin(th), -math.sin(ph)),
            atol=2e-5,
        )
        # the load P at (x, y, z), the thread's hanging run ends on it
        np.testing.assert_allclose(load.position, (x, y, z), atol=1e-3)
        np.testing.assert_allclose(thread.points[-1, 1], (x, y, z + LOAD_RADIUS), atol=1e-3)
        # the frame rides on P's (x, y) at heading θ
        np.testing.assert_allclose(node(app, "frames/body").position, (x, y, 0), atol=1e-3)


def test_wheel_rolls_without_slipping_in_the_scene(app):
    """Between two frames the wheel centre moves by a·Δφ along the heading (51)–(52)."""
    run, a = app.traj.main, app.traj.params["a"]
    wheel = node(app, "frames/wheel")
    positions = []
    for t in (5.0, 5.01):
        app.seek(t)
        positions.append(np.array(wheel.position, float))
    k0, k1 = geo.index_at(run.t, 5.0), geo.index_at(run.t, 5.01)
    dphi = run.state["phi"][k1] - run.state["phi"][k0]
    th = run.state["theta"][k0]
    step = positions[1] - positions[0]
    assert np.linalg.norm(step) == pytest.approx(abs(a * dphi), rel=2e-2)
    axle = (-math.sin(th), math.cos(th), 0.0)
    assert abs(np.dot(step / np.linalg.norm(step), axle)) < 2e-2  # no side slip


def test_fig7_trace_is_the_load_path_on_the_plane(app):
    run = app.traj.main
    segs = node(app, "world/trace").points
    assert len(segs) <= 2000
    np.testing.assert_allclose(segs[0, 0, :2], (run.state["x"][0], run.state["y"][0]), atol=1e-4)
    np.testing.assert_allclose(segs[-1, 1, :2], (run.state["x"][-1], run.state["y"][-1]), rtol=1e-6)


def test_load_falls_below_the_plane_and_the_bar_reaches_it(app):
    app.control("t_final").value = 40.0
    run = app.traj.main
    k = int(np.argmin(run.state["z"]))
    z_min = float(run.state["z"][k])
    assert z_min < -50  # the paper's model: no floor
    app.seek(float(run.t[k]))
    pit = node(app, "world/pit").points  # the bar below the plane, through the hole
    assert pit[0, :, 2].min() < z_min - LOAD_RADIUS


def test_singular_start_shows_status_and_a_moving_scene(app):
    app.control("initial.u2").value = 0.0  # the nonlinear model's J2 is singular at φ̇ = 0
    run = app.traj.main
    assert run.t[-1] > 0
    assert "nonlinear → linear" in app.status.content  # the library's switch is reported
    app.control("initial.u2").value = 1.0
    app.control("variant").value = "nonlinear"
    app.control("initial.u2").value = 0.0
    assert "**nonlinear: ok**" in app.status.content or "⚠" in app.status.content


def test_unstable_gain_result_is_reported_in_the_panel(app):
    app.control("dt").value = 0.2
    app.control("gamma").value = 10.0  # positive Γ: unstable constraint error dynamics
    run = app.traj.main
    assert run.settings["gamma"] == 10.0
    assert run.summary["status"] in app.status.content and "not stable" in app.status.content
    assert np.all(np.isfinite(run.state["x"])) and np.isfinite(node(app, "world/trace").points).all()


def test_compare_ghost_animates_the_other_model(app):
    compare = app.control("option.compare")
    assert compare.value == "off" and set(compare.options) >= {"off", "linear", "Γ = 0"}
    compare.value = "linear"
    assert list(app.traj.runs) == ["nonlinear", "linear"]
    ghost = app.system_view.ghosts[0]
    assert ghost.root.visible and ghost.ghost is not None
    app.seek(5.0)
    other = app.traj.runs["linear"]
    k = geo.index_at(other.t, 5.0)
    np.testing.assert_allclose(ghost.frames["body"].position, (other.state["x"][k], other.state["y"][k], 0), atol=1e-4)
    wheel = app.scene.get_handle_by_name(f"/sys/{AH}/ghost1/frames/wheel/disk")
    assert wheel.opacity is not None and wheel.opacity < 1 and tuple(wheel.color) != (48, 88, 196)  # translucent
    assert "linear" in app.summary.content and "rolling_x" in app.summary.content
    series = app.plot_handles[(AH, "energy")].series
    assert series[2]["dash"] and "dash" not in series[1]  # the compare run's curve dashed
    compare.value = "off"
    assert list(app.traj.runs) == ["nonlinear"] and not ghost.root.visible


def test_plots_show_the_run_with_a_current_time_marker(app):
    app.control("option.plot").value = "theta"
    app.seek(7.5)
    for key, h in app.plot_handles.items():
        if key[0] != AH:
            continue
        t, *ys = h.data
        assert len(t) <= pl.MAX_POINTS and t[0] == 0.0 and t[-1] == pytest.approx(app.traj.t_end)
        assert all(np.all(np.isfinite(y)) for y in ys)  # never NaN (uPlot drops the curve)
        marker = h.axes[2]  # the hidden top axis' grid line
        assert marker["splits"] == (7.5,) and marker["grid"]["show"]
    theta = app.plot_handles[(AH, "coord")].data[1]
    assert theta.min() == pytest.approx(app.traj.main.state["theta"].min(), abs=1e-9)
    assert len(app.plot_handles[(AH, "violation")].data) == 1 + 3
    assert "rolling_speed" in app.summary.content and "max \\|ΔE\\|" in app.summary.content


def test_playback_advances_time_and_pause_holds_it(app):
    app.seek(1.0)
    app.tick(0.5, refresh=True)
    assert app.t_now == pytest.approx(1.5)
    app.speed.value = 4.0
    app.tick(0.25, refresh=True)
    assert app.t_now == pytest.approx(2.5) and app.time.value == pytest.approx(2.5)
    app.play.value = True  # the button: pause
    assert not app.playing and "Play" in app.play.label
    app.tick(1.0, refresh=True)
    assert app.t_now == pytest.approx(2.5)
    app.time.value = 4.0  # the scrubber seeks
    assert app.t_now == pytest.approx(4.0)


def test_reset_restores_the_papers_values_in_one_run(app):
    app.control("gamma").value = -3.0
    app.control("params.m").value = 2.0
    n = len(app.sim_log)
    app.reset.value = True
    assert len(app.sim_log) == n + 1
    s = app.sim_log[-1]
    assert s["gamma"] == 0.0 and s["params"]["m"] == 1.0  # the paper's Example 1: no stabilization
    assert s["dt"] == 0.01 and s["t_final"] == 20.0 and s["model"] == "nonlinear"
    assert (s["initial"]["u1"], s["initial"]["u2"]) == (1.0, 1.0)


def test_particle_shows_minimal_undamped_and_damped_solutions_as_ghosts(app):
    """The paper's Fig. 16 comparison through the generic page: the damped nonminimal run (DN)
    shown, the minimal (M) and the undamped (N, Γ = 0) runs as ghosts (the system's showcase)."""
    choose(app, PT)
    assert list(app.traj.runs) == ["nonminimal", "minimal", "nonminimal, Γ = 0"]
    runs = app.traj.runs
    assert runs["nonminimal"].settings["gamma1"] == -20.0 and runs["nonminimal, Γ = 0"].settings["gamma1"] == 0.0
    assert runs["minimal"].settings["formulation"] == "minimal"
    assert app.traj.request["settings"]["dt"] == 0.05 and app.traj.t_end == pytest.approx(300.0)
    view = app.system_view
    assert view.root.visible and not app.views[AH].root.visible
    app.control("gamma1").value = -10.0
    assert app.traj.runs["nonminimal"].settings["gamma1"] == -10.0
    app.seek(120.0)
    balls = [view.declared, *view.ghosts[:2]]
    for scene, (lab, run) in zip(balls, app.traj.runs.items(), strict=True):
        k = geo.index_at(run.t, 120.0)
        ball = app.scene.get_handle_by_name(f"{scene.prefix}/world/particle")
        np.testing.assert_allclose(ball.position, (run.state["x"][k], 0.0, -run.state["y"][k]), atol=1e-5, err_msg=lab)
    # the undamped solution drifts off the surface, the damped one stays near it (Fig. 16)
    s = {lab: r.summary["max_abs_violation"]["surface"] for lab, r in app.traj.runs.items()}
    assert s["minimal"] == 0.0 and s["nonminimal"] < 1e-2 * s["nonminimal, Γ = 0"]
    labels = [x["label"] for x in app.plot_handles[(PT, "violation")].series[1:]]
    assert labels == ["surface — nonminimal", "surface — minimal, dashed", "surface — nonminimal, Γ = 0, dotted"]


def test_background_worker_latest_wins_and_each_change_installs_one_run(server):
    a = MechanismApp(server)  # the real, threaded path
    try:
        assert a.wait_idle(60)
        for g in np.arange(-1.0, -11.0, -0.5):  # a drag: 20 events
            a.control("gamma").value = float(g)
        assert a.wait_idle(30)
        assert a.traj.main.settings["gamma"] == -10.5
        assert len(a.sim_log) < 1 + 20
        # one change at a time: each installs exactly its run (the latency, target 0.1 s, is printed:
        # a wall-clock bound on a loaded 2-core machine fails by chance; wait_idle bounds a stall)
        lat = []
        for g in (-2.0, -3.0, -4.0, -5.0, -6.0):
            runs = len(a.sim_log)
            a.control("gamma").value = g
            assert a.wait_idle(10)
            assert a.traj.main.settings["gamma"] == g and len(a.sim_log) == runs + 1
            lat.append(a.latencies[-1])
        print(f"control change -> new trajectory installed: median {np.median(lat) * 1e3:.0f} ms")
    finally:
        a.close()


def test_latest_worker_coalesces_bursts():
    seen = []
    w = LatestWorker(lambda r: (seen.append(r), time.sleep(0.05)), debounce=0.01)
    for i in range(20):
        w.submit(i)
    assert w.wait_idle(5)
    w.close()
    assert seen[-1] == 19 and len(seen) <= 3


def test_envelope_decimation_keeps_extremes():
    t = np.linspace(0, 10, 100_001)
    y = np.sin(t)
    y[54_321] = 50.0  # a one-sample spike survives thinning
    td, (yd,) = pl.envelope(t, [y], 1000)
    assert len(td) <= 1000 and yd.max() == 50.0 and yd.min() == pytest.approx(-1.0, abs=1e-6)
    assert np.all(np.diff(td) >= 0)


def test_matrices_panel_draws_the_derived_matrices():
    panel = mx.panel("sliding-particle", "nonminimal")
    assert set(panel.images) == {"A1", "A2", "T", "V"}
    for img in panel.images.values():
        assert img.dtype == np.uint8 and img.shape[2] == 4 and img[..., :3].min() < 100  # ink on white
    assert "x" in panel.latex["T"] and "l_{0}" in panel.latex["T"]


def test_launch_serves_and_stops():
    handle = launch(port=0)
    try:
        assert handle.port > 0
        deadline = time.monotonic() + 30  # the animation thread runs: frames counted, not a rate
        while len(handle.frame_times) < 20:
            assert time.monotonic() < deadline, "the animation thread does not run"
            time.sleep(0.05)
        import urllib.request

        html = urllib.request.urlopen(f"http://127.0.0.1:{handle.port}/", timeout=10).read()
        assert b"<html" in html[:2000].lower()
    finally:
        handle.stop()


def test_software_webgl_starts_without_shadows(app):
    from web.page import is_software

    assert app.shadows.value is True  # a graphics card: shadows
    app._on_page({"kind": "renderer", "name": "ANGLE (NVIDIA, NVIDIA GeForce RTX 3060 Direct3D11 vs_5_0 ps_5_0)"})
    assert app.renderer.startswith("ANGLE (NVIDIA") and app.shadows.value is True
    swiftshader = "ANGLE (Google, Vulkan 1.3.0 (SwiftShader Device (Subzero) (0x0000C0DE)), SwiftShader driver)"
    assert is_software(swiftshader) and is_software("llvmpipe (LLVM 15.0.6, 256 bits)")
    app._on_page({"kind": "renderer", "name": swiftshader})
    assert app.shadows.value is False


def test_the_web_apps_warm_up_ends_with_the_system_under_way_once_the_app_stops(monkeypatch):
    """A stopped app's warm-up does not go on compiling every other system in the background."""
    import threading

    import nmkane_core.run.simulate as core_simulate
    import web.server as srv

    stop, ran, panels = threading.Event(), [], []

    def fake(settings, **_):
        ran.append(settings["system"])
        stop.set()  # the app stops while the first system warms

    monkeypatch.setattr(core_simulate, "simulate", fake)
    monkeypatch.setattr(srv.mx, "panel", lambda *key: panels.append(key))
    srv.warm(stop)
    assert ran and set(ran) == {ran[0]} and panels == [], (ran, panels)


def test_a_paused_phase_portraits_current_point_follows_a_seek(app):
    """The portrait's current point (two grid lines crossing there) moves with every seek, also
    while paused, and only its axes are sent again (not its data)."""
    app.control("option.plot").value = "y"
    app.control("option.plot_x").value = "x"
    app.set_playing(False)
    chart = app.plots.phases[AH]
    data = chart.data
    app.seek(2.0)
    run = app.traj.main
    k = int(np.searchsorted(run.t, 2.0, side="right")) - 1
    assert chart.axes[2]["splits"] == (pytest.approx(run.state["x"][k]),)
    assert chart.axes[3]["splits"] == (pytest.approx(run.state["y"][k]),)
    x, y = run.state["x"][k], run.state["y"][k]
    assert chart.title.endswith(f"at t = 2 s: x = {x:.4g}, y = {y:.4g}")  # the point's values, in words
    app.seek(5.0)
    k = int(np.searchsorted(run.t, 5.0, side="right")) - 1
    assert chart.axes[2]["splits"] == (pytest.approx(run.state["x"][k]),) and chart.data is data
    assert f"x = {run.state['x'][k]:.4g}" in chart.title


def test_the_status_says_which_speeds_the_run_took_independent(app):
    """Issue 45 item 4: the partition in view (the summary's ``partition``)."""
    assert "nonlinear: u_I = u1, u2 · q solved from ψ = 0: z (declared)" in app.status.content
    choose(app, PT)
    assert "u_I = u1 · q solved from ψ = 0: y (declared)" in app.status.content
