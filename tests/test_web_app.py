"""The web app in-process (no browser): controls re-simulate with their settings, and the
scene nodes sit where the state puts them."""

import math
import time

import numpy as np
import pytest
import viser

from web import geometry as geo
from web.app import LatestWorker, Session, WebApp, matrices_markdown


@pytest.fixture(scope="module", autouse=True)
def _matrices_ready():
    # the matrices panel's symbolic text is computed once per process (the app warms it at start)
    for variant in ("nonlinear", "linear"):
        matrices_markdown("appell-hamel", variant)
    matrices_markdown("sliding-particle", "nonminimal")


@pytest.fixture()
def server():
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


@pytest.fixture()
def session(server):
    s = Session(server.gui, server.scene, sync=True)
    yield s
    s.close()


def _quat_angle_about(wxyz, axis):
    w, x, y, z = wxyz
    v = np.array([x, y, z])
    return math.remainder(2 * math.atan2(float(np.dot(v, axis)), w), 2 * math.pi)


def test_slider_changes_resimulate_with_those_settings(session):
    n0 = len(session.sim_log)
    session.gamma.value = -7.5
    session.model.value = "linear"
    session.log_dt.value = -2.5
    assert len(session.sim_log) == n0 + 3
    last = session.sim_log[-1]
    assert last["gamma"] == -7.5 and last["model"] == "linear"
    assert abs(last["dt"] - 10 ** -2.5) < 1e-12
    assert session.traj.main.settings["model"] == "linear"
    assert session.traj.main.settings["gamma"] == -7.5


def test_initial_speed_sliders_complete_the_dependent_speeds(session):
    session.theta_dot0.value = 0.5
    session.phi_dot0.value = -1.0
    st = session.traj.main.state
    assert st["u1"][0] == 0.5 and st["u2"][0] == -1.0
    # completed by the library's constraint solve: ẋ = aφ̇cosθ − ρθ̇sinθ at θ = 0
    assert abs(st["u3"][0] - (-1.0)) < 1e-12 and abs(st["u4"][0] - 0.5 * 5.0) < 1e-12


def test_scene_nodes_follow_the_state_at_time_t(session):
    run = session.traj.main
    p = session.traj.params
    for t in (0.0, 3.3, 12.0):
        session.show_time(t)
        k = min(int(np.searchsorted(run.t, t)), len(run.t) - 1)
        th, ph, x, y, z = (run.state[n][k] for n in ("theta", "phi", "x", "y", "z"))
        np.testing.assert_allclose(session.frame.position, (x, y, 0.0), atol=1e-9)
        assert abs(_quat_angle_about(session.frame.wxyz, (0, 0, 1)) - math.remainder(th, 2 * math.pi)) < 1e-9
        spin = session._frame_parts["/ah/frame"]["spin"].wxyz
        assert abs(_quat_angle_about(spin, (0, 1, 0)) - math.remainder(ph, 2 * math.pi)) < 1e-9
        np.testing.assert_allclose(session._frame_parts["/ah/frame"]["load"].position, (0, 0, z), atol=1e-9)
        # wheel centre in the world: P's position − ρ(cos θ, sin θ) at height a  (53)–(54)
        c = geo.wheel_centre_world(p, th, x, y)
        local = np.array(geo.wheel_centre_local(p))
        rot = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0], [0, 0, 1]])
        np.testing.assert_allclose(np.array([x, y, 0.0]) + rot @ local, c, atol=1e-9)


def test_singular_setting_shows_status_not_a_frozen_scene(session):
    session.phi_dot0.value = 0.0            # J2 singular at t = 0: the run switches models
    assert session.traj is not None
    text = session.status.content
    assert "ok" in text and "nonlinear → linear" in text


def test_unstable_gain_result_is_reported_in_the_panel(session):
    session.log_dt.value = math.log10(0.2)
    session.gamma.value = 10.0                # positive Γ: unstable constraint dynamics
    text = session.status.content
    run = session.traj.main
    assert run.settings["gamma"] == 10.0
    assert run.summary["status"] in text and "not stable" in text
    assert np.all(np.isfinite(run.state["x"]))


def test_compare_ghost_runs_the_other_model(session):
    session.compare.value = True
    assert set(session.traj.runs) == {"nonlinear", "linear"}
    assert session.ghost.visible
    session.show_time(5.0)
    ghost = session.traj.runs["linear"]
    k = int(np.searchsorted(ghost.t, 5.0))
    np.testing.assert_allclose(session.ghost.position, (ghost.state["x"][k], ghost.state["y"][k], 0), atol=1e-9)


def test_particle_scene_shows_three_solutions(session):
    session.scene_choice.value = "Sliding particle"
    assert set(session.traj.runs) == {"M", "N", "DN"}
    assert session.traj.runs["DN"].settings["gamma1"] == -20.0
    session.gamma1.value = -10.0
    assert session.traj.runs["DN"].settings["gamma1"] == -10.0
    session.show_time(2.0)
    run = session.traj.runs["N"]
    k = int(np.searchsorted(run.t, 2.0))
    np.testing.assert_allclose(session.pt_particles[1].position,
                               (run.state["x"][k], 0.0, -run.state["y"][k]), atol=1e-9)


def test_plots_receive_the_trajectory(session):
    session.show_time(0.0)
    session._write_plots(session.traj, session.traj.t_end)
    t, dE = session.plot_energy.data[:2]
    assert t[-1] == pytest.approx(session.traj.t_end) and np.all(np.isfinite(dE))
    assert len(session.plot_viol.data) == 4


def test_latest_worker_coalesces_bursts():
    seen = []
    w = LatestWorker(lambda r: (seen.append(r), time.sleep(0.05)), debounce=0.02)
    for i in range(20):
        w.submit(i)
    assert w.wait_idle(5)
    w.close()
    assert seen[-1] == 19 and len(seen) <= 3


def test_resimulation_after_a_slider_change_is_fast():
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    try:
        s = Session(srv.gui, srv.scene)
        assert s.worker.wait_idle(60)
        times = []
        for g in (-1.0, -2.0, -3.0, -4.0):
            t0 = time.perf_counter()
            s.gamma.value = g
            assert s.worker.wait_idle(10)
            times.append(time.perf_counter() - t0)
            assert s.traj.main.settings["gamma"] == g
        s.close()
        assert min(times) < 1.0          # typical: tens of ms (speed is measured by the bench)
    finally:
        srv.stop()


def test_web_app_starts_and_stops():
    app = WebApp(port=0)
    try:
        assert app.port > 0
    finally:
        app.stop()
