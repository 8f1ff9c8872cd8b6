"""The web app's "Γ study" panel: its map is the sweep of direct ``simulate`` runs, a chosen
cell goes into the sliders, it is generic over systems, and it never holds the animation."""

import math
import time

import numpy as np
import pytest

from nmkane_core.run.simulate import simulate
from web.controls import DT_RANGE, Control, dt_of
from web.session import MechanismApp
from web.study import GAIN_FIELDS, METRICS, N_DT, N_GAIN, study_axes


@pytest.fixture()
def app(server):
    a = MechanismApp(server, sync=True)
    yield a
    a.close()


def _title(app, system):
    return next(t for t, n in app.choices.items() if n == system)


def _computed(app, gain_label="Γ"):
    st = app.study
    st.gain.value = gain_label
    assert st.start() is not None
    assert st.wait(300)
    assert st.error is None and st.grid is not None, st.note.content
    return st


def _log(v):
    return math.log10(max(v, 1e-16))


def _direct(grid, i, j):
    """The cell's run, by simulate itself, from the grid's base settings."""
    s = {**grid.base, grid.gain: grid.gains[i], "dt": grid.dts[j]}
    return simulate(s, progress=False).summary


def test_study_axes_stay_on_the_sliders():
    c = Control("g", "Γ", "gamma", 0.0, min=-50.0, max=10.0, step=0.5)
    gains, log_dts = study_axes((c,), "gamma", -2.0)
    assert gains == (-50.0, -40.0, -30.0, -20.0, -10.0, 0.0) and len(gains) == N_GAIN
    assert log_dts == (-3.0, -2.5, -2.0, -1.5, -1.0) and len(log_dts) == N_DT
    lo, hi = (math.log10(v) for v in DT_RANGE)
    for edge in (-4.0, hi):  # at an end of the Δt slider the window shifts inside it
        _, ld = study_axes((c,), "gamma", edge)
        assert lo - 1e-9 <= min(ld) and max(ld) <= hi + 1e-9 and len(ld) == N_DT
    with pytest.raises(ValueError, match="gamma2"):
        study_axes((c,), "gamma2", -2.0)


def test_map_equals_direct_simulate_runs_and_a_cell_loads_into_the_sliders(app):
    app.control("dt").value = 0.01
    app.control("gamma1").value = -20.0  # the other gains stay as the sliders say
    st = _computed(app)
    g = st.grid
    assert g.gain == "gamma" and g.base["gamma1"] == -20.0 and g.base["t_final"] == 2.0
    assert g.dts == tuple(dt_of(v) for v in g.log_dts) and len(g.rows) == N_GAIN * N_DT
    zv = g.z("log10 max|violation|")
    ze = g.z("log10 max|ΔE| (energy error)")
    for i, j in ((3, 1), (5, 4), (0, 0)):
        s = _direct(g, i, j)
        assert s["status"] == "ok"
        assert zv[j, i] == _log(max(s["max_abs_violation"].values()))
        assert ze[j, i] == _log(s["max_abs_energy_drift"])
    bad = g.status()  # a run that did not end ok is NaN on the map, with its status
    for (j, i), status in bad.items():
        assert math.isnan(zv[j, i]) and _direct(g, i, j)["status"] == status
    assert st.image.visible and st.image.image.shape[2] == 4

    # choose a cell in the dropdown, load it: the sliders and the next run take its settings
    cell = (2, 4)
    label = g.label(cell, st.metric.value)
    st.cell.value = label
    st.load_button._impl.update_cb[0](None)  # the button's click
    assert app.control("gamma").value == g.gains[4] and app.control("dt").value == g.dts[2]
    last = app.sim_log[-1]
    assert last["gamma"] == g.gains[4] and last["dt"] == g.dts[2] and last["gamma1"] == -20.0
    assert app.traj.main.settings["gamma"] == g.gains[4]

    before = st.image.image.copy()  # another colour: the map is drawn again, the same cell kept
    st.metric.value = "log10 max|ΔE| (energy error)"
    assert st.cell.value == g.label(cell, st.metric.value) and st.cell.value in st.cell.options
    assert f"→ {ze[2, 4]:.2f}" in st.cell.value and not np.array_equal(before, st.image.image)
    st.metric.value = "log10 max|violation|"

    assert st.load_best()  # the smallest value on the map
    j, i = np.unravel_index(np.nanargmin(zv), zv.shape)
    assert app.control("gamma").value == g.gains[i] and app.control("dt").value == g.dts[j]
    assert st.cell.value == g.label((int(j), int(i)), st.metric.value)


def test_holonomic_gains_and_a_generic_system(app):
    app.scene_choice.value = _title(app, "sliding-particle")
    assert app.study.gain.options == ("Γ1", "Γ2")  # holonomic only: no Γ
    st = _computed(app, "Γ2")
    g = st.grid
    assert g.gain == "gamma2" and g.gains[0] == -500.0 and g.gains[-1] == 0.0
    s = _direct(g, 1, 2)
    assert g.z(next(iter(METRICS)))[2, 1] == _log(max(s["max_abs_violation"].values()))
    assert st.load((2, 1))
    assert app.control("gamma2").value == g.gains[1] and app.traj.main.settings["gamma2"] == g.gains[1]

    app.scene_choice.value = _title(app, "knife-edge")  # a system from its declaration alone
    assert app.study.grid is None and app.study.gain.options == ("Γ",)
    st = _computed(app)
    g = st.grid
    assert g.kind == "knife-edge" and g.base["system"] == "knife-edge"
    s = _direct(g, 2, 3)
    assert g.z(next(iter(METRICS)))[3, 2] == _log(max(s["max_abs_violation"].values()))
    assert st.load((3, 2))
    handles = {c.field: h for c, h in app.sim_controls[app.kind].items()}
    assert handles["gamma"].value == g.gains[2] and app.sim_log[-1]["dt"] == g.dts[3]
    assert set(GAIN_FIELDS) >= {"gamma", "gamma1", "gamma2"}


def test_a_scene_change_drops_a_running_study_and_a_stale_map_is_not_loaded(app):
    st = _computed(app)
    app.scene_choice.value = _title(app, "sliding-particle")
    assert st.grid is None and not st.load((0, 0))  # the map was of another system

    st.gain.value = "Γ1"
    st.horizon.value = 20.0  # long enough to be running when the scene changes
    st.start()
    app.scene_choice.value = _title(app, "knife-edge")
    assert st.wait(300)
    assert st.grid is None  # the superseded study left nothing behind


def test_the_animation_keeps_running_during_a_study(app):
    st = app.study
    st.horizon.value = 20.0
    st.start()
    longest, frames = 0.0, 0
    while st.thread.is_alive() and frames < 2000:
        t0 = time.perf_counter()
        app.tick(1 / 60, refresh=True)
        longest = max(longest, time.perf_counter() - t0)
        frames += 1
        time.sleep(0.005)
    assert st.wait(300)
    print(f"{frames} frames during the study, longest {longest * 1e3:.1f} ms")
    assert frames > 0
    assert st.grid is not None and len(st.grid.rows) == N_GAIN * N_DT
