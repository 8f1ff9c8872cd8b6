"""The generic page (no browser): every registered system can be chosen, its controls come
from its declaration, its declared scene follows the state, a plugged-in system works, and
``scene=`` opens a browser on a system.  Also the performance targets (server side)."""

import time
from pathlib import Path

import numpy as np
import pytest
import viser

from nmkane_core.errors import InputError
from nmkane_core.kernel.visuals import compile_visuals
from nmkane_core.run.plugins import load_systems
from nmkane_core.run.registry import get_system, system_names
from web.app import MechanismApp
from web.generic import parameter_control

CATALOGUE = ("knife-edge", "chaplygin-sleigh", "rolling-disk", "odometer-puck", "iftomm-a02", "iftomm-a04")
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "isokinetic_bowl.py"


@pytest.fixture()
def app(module_server):
    a = MechanismApp(module_server, sync=True)
    yield a
    a.close()


def choose(app, name):
    title = next(t for t, n in app.choices.items() if n == name)
    app.scene_choice.value = title
    assert app.system_view.system == name
    assert app.traj is not None and app.traj.kind == app.kind
    return app.system_view


def handle(app, field):
    return next(h for c, h in app.sim_controls[app.kind].items() if c.field == field)


def test_the_scene_chooser_lists_every_registered_system(app):
    assert set(app.choices.values()) == set(system_names())
    assert len(app.choices) == len(set(app.choices))


@pytest.mark.parametrize("name", CATALOGUE)
def test_each_catalogue_system_runs_and_its_scene_follows_the_state(app, name):
    view = choose(app, name)
    run = app.traj.main
    assert run.system == name and run.summary["status"] == "ok"
    assert app.folders[app.kind].visible and view.root.visible
    assert not any(v.root.visible for v in app.views.values() if v is not view)
    # the frame nodes sit where the compiled pose functions put them at the shown time
    app.set_playing(False)
    t = 0.37 * app.traj.t_end
    app.seek(t)
    k = int(np.searchsorted(run.t, t, side="right")) - 1
    frames, _ = compile_visuals(get_system(name)).frame_poses(
        {n: v[k : k + 1] for n, v in run.state.items()}, app.traj.params
    )
    for fname, (pos, _rot) in frames.items():
        np.testing.assert_allclose(view.declared.frames[fname].position, pos[0], atol=1e-9)
    # the plots show this run: energy drift, one violation curve per constraint, a coordinate
    labels = [s["label"] for s in app.plots.handles[(app.kind, "violation")].series[1:]]
    assert labels == list(run.violation)
    assert app.plots.handles[(app.kind, "energy")].visible


def test_controls_come_from_the_declaration(app):
    choose(app, "knife-edge")
    fields = {c.field for c in app.sim_controls[app.kind]}
    assert "gamma" in fields and "gamma1" not in fields and "gamma2" not in fields  # nonholonomic only
    assert {"initial.x", "initial.y", "initial.theta", "initial.u1", "initial.u3"} <= fields
    assert "initial.u2" not in fields  # dependent speed
    assert {"integrator", "projection", "dt", "t_final", "option.plot"} <= fields
    # a parameter spanning decades gets a log slider, and its value reaches the run
    h = handle(app, "params.m")
    h.value = 4.0
    assert app.traj.request["settings"]["params"]["m"] == pytest.approx(4.0)
    assert app.traj.main.settings["params"]["m"] == pytest.approx(4.0)
    handle(app, "initial.u3").value = 0.0  # no turning: a straight line
    y = app.traj.main.state["y"]
    assert np.max(np.abs(y)) < 1e-12
    handle(app, "option.plot").value = "u1"
    assert app.traj.plots["coord"].labels == ["u1"]


def test_parameter_sliders_linear_or_log():
    from nmkane_core import Parameter

    lin = parameter_control(Parameter(9.81, 0.0, 30.0, "m/s²", min_inclusive=True, name="g"), "x_")
    assert lin.field == "params.g" and (lin.min, lin.max) == (0.0, 30.0)
    log = parameter_control(Parameter(1.0, 0.0, 100.0, "kg", name="m"), "x_")
    assert log.field == "params.m" and log.log and (log.min, log.max) == (0.01, 100.0) and log.default == 1.0
    assert log.label == "m [kg]"  # typed and shown in kg, not as an exponent


def test_a_plugged_in_system_gets_the_generic_page(module_server):
    assert load_systems([str(EXAMPLE)]) == []
    a = MechanismApp(module_server, sync=True, scene="isokinetic-bowl")
    try:
        assert a.system_view.system == "isokinetic-bowl"
        run = a.traj.main
        assert run.system == "isokinetic-bowl" and run.summary["status"] == "ok"
        fields = {c.field for c in a.sim_controls[a.kind]}
        assert {"gamma", "gamma1", "gamma2"} <= fields  # both kinds of constraints
        d = a.system_view.declared
        assert d.compiled is not None  # the file declares its visuals: the bowl, the particle, its path
        a.set_playing(False)
        a.seek(1.0)
        k = int(np.searchsorted(run.t, 1.0, side="right")) - 1
        ball = a.scene.get_handle_by_name("/sys/isokinetic-bowl/world/particle")
        np.testing.assert_allclose(ball.position, [run.state[n][k] for n in ("x", "y", "z")], atol=1e-5)
        # a system without a second variant still compares: the same run without stabilization
        a.control("gamma").value = -5.0
        a.control("option.compare").value = "Γ = 0"
        assert list(a.traj.runs) == ["default", "default, Γ = 0"]
        assert a.traj.runs["default, Γ = 0"].settings["gamma"] == 0.0 and a.system_view.ghosts[0].root.visible
    finally:
        a.close()


def test_scene_option_opens_on_a_system_and_an_unknown_one_is_refused(module_server):
    a = MechanismApp(module_server, sync=True, scene="rolling-disk")
    try:
        assert a.kind == "rolling-disk" and a.traj.kind == a.kind
        assert len(a.sim_log) == 1  # one run: no detour through the first scene
    finally:
        a.close()
    from web.server import launch, launch_app

    with pytest.raises(InputError, match="scene"):
        launch(port=0, scene="no-such-system")
    handle = launch_app("127.0.0.1", 0, scene="knife-edge")  # what `nmkane serve --scene` passes
    try:
        assert handle.scene == "knife-edge"
    finally:
        handle.stop()


def test_performance_switch_and_slider_to_new_motion(app):
    """Switching to a system and a slider change both lead to the new motion.  The targets
    (switching ≤ 1 s with kernels cached, a slider change to new motion ≤ 100 ms on the server)
    are measured and printed here (`pytest -s`); the assertions only guard against a hang —
    timings on a loaded 2-core CI machine (every kernel compiling next door) are no correctness
    claim, and a timed assertion there fails now and then."""
    for name in CATALOGUE:  # kernels, loops and visuals loaded once (the server warms them)
        choose(app, name)
    other = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    fresh = MechanismApp(other, sync=True)  # a new browser: each system's page is built on first choice
    try:
        for name in CATALOGUE:
            t0 = time.perf_counter()
            choose(fresh, name)
            first = time.perf_counter() - t0
            assert first <= 30.0, (name, first)
            print(f"{name}: first choice (page built) {first * 1e3:.0f} ms")
    finally:
        fresh.close()
        other.stop()
    for name in ("appell-hamel", "sliding-particle", *CATALOGUE):  # the paper's two: the same page
        away = "knife-edge" if name == "appell-hamel" else "appell-hamel"
        choose(app, name)
        switch = []
        for _ in range(3):
            choose(app, away)
            t0 = time.perf_counter()
            choose(app, name)
            switch.append(time.perf_counter() - t0)
        assert min(switch) <= 30.0, (name, switch)
        h = handle(app, "t_final")
        slider = []
        for _ in range(3):
            t0 = time.perf_counter()
            h.value = h.value + h.step
            slider.append(time.perf_counter() - t0)
            assert app.traj.request["settings"]["t_final"] == pytest.approx(h.value)
        assert min(slider) <= 10.0, (name, slider)
        print(f"{name}: switch {min(switch) * 1e3:.0f} ms, slider → new motion {min(slider) * 1e3:.0f} ms")
