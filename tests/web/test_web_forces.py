"""Constraint forces on the page (issue 22, item 4): the arrows at their points, scaled by the
scale they show, the |F| plot beside energy and violation, the readout at the time cursor, and
the "Show forces" checkbox."""

import types

import numpy as np
import pytest

from nmkane_core.run.registry import get_system
from web.app import MechanismApp
from web.forces import TITLE, force_curves, nice_scale, readout


def test_nice_scale_rounds_newtons_per_metre_up_to_1_2_5():
    assert 1 / nice_scale(9.8, 0.6) == pytest.approx(20.0)  # 16.3 N/m → 20
    assert 1 / nice_scale(3.0, 1.0) == pytest.approx(5.0)
    assert 1 / nice_scale(100.0, 1.0) == pytest.approx(100.0)
    assert 1 / nice_scale(0.011, 1.0) == pytest.approx(0.02)
    for largest, length in ((9.8, 0.6), (0.37, 0.2), (1234.0, 1.5)):
        assert largest * nice_scale(largest, length) <= length * (1 + 1e-12)  # never longer than asked
        assert largest * nice_scale(largest, length) > 0.19 * length  # nor much shorter
    assert nice_scale(0.0, 1.0) == 1.0 and nice_scale(float("nan"), 1.0) == 1.0


def _run(t, comps):
    return types.SimpleNamespace(t=np.asarray(t, float), point_forces=comps, settings={})


def test_readout_names_each_force_its_magnitude_and_components_at_the_cursor():
    run = _run([0.0, 1.0, 2.0], {"contact.lateral": np.array([0.0, 3.0, 1.0]), "contact.normal": np.array([1, 4, 1.0])})
    text = readout(run, 1.5)  # the row at or before the cursor
    assert text.startswith("t = 1 s") and "**contact** 5 N" in text
    assert "lateral 3" in text and "normal 4" in text
    assert readout(_run([0.0], {}), 0.0) == ""


def test_force_curves_give_the_magnitude_of_each_force_and_none_without_forces():
    core = get_system("knife-edge")
    t = np.linspace(0.0, 1.0, 5)
    run = _run(t, {"blade.lateral": -2.0 * np.ones(5)})
    run.settings = {core.option: core.default_variant}
    out = force_curves(core, {"main": run}, t, lambda r, v: v)
    assert out is not None and out.labels == ["|blade|"]
    np.testing.assert_allclose(out.ys[0], 2.0)
    assert force_curves(core, {"main": _run(t, {})}, t, lambda r, v: v) is None


def test_rolling_disk_draws_its_contact_force_at_scale_and_the_checkbox_hides_it(server):
    app = MechanismApp(server, sync=True, scene="rolling-disk")
    try:
        view = app.system_view
        arrows = view.forces
        assert arrows.declared and arrows.visible  # on by default: the coin's friction turns it
        assert view.force_panel.box.value is True
        assert ("forces", TITLE) in view.plots and "forces" in app.traj.plots
        app.set_playing(False)
        app.seek(2.0)
        run = app.traj.main
        k = view.k
        node = app.scene.get_handle_by_name(f"/sys/{app.kind}/forces/contact")
        assert node is arrows.arrows["contact"] and node.visible
        tail = np.asarray(node.position, float)
        length = node.scale[2] * np.linalg.norm(np.diff(np.asarray(node.points, float)[0], axis=0))
        comps = [run.point_forces[f"contact.{c}"][k] for c in ("longitudinal", "lateral", "normal")]
        assert length == pytest.approx(np.linalg.norm(comps) * arrows.scale, rel=1e-5)
        w, x, y, z = node.wxyz  # the arrow's z turned onto the force (normal up: mostly vertical)
        along = np.array([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
        vec = arrows.vectors["contact"][k]
        np.testing.assert_allclose(along, vec / np.linalg.norm(vec), atol=1e-6)
        np.testing.assert_allclose(tail[:2], [run.state["x"][k], run.state["y"][k]], atol=1e-5)
        assert "**contact**" in view.force_panel.text.content
        assert f"1 m = {1 / arrows.scale:g} N" in view.force_panel.text.content  # the scale: here, not in the scene
        assert app.scene.get_handle_by_name(f"/sys/{app.kind}/forces/scale") is None
        view.force_panel.box.value = False
        assert not arrows.visible and not app.scene.get_handle_by_name(f"/sys/{app.kind}/forces").visible
        view.force_panel.box.value = True
        assert arrows.visible
    finally:
        app.close()


def test_a_system_without_declared_forces_has_no_forces_plot_or_checkbox(server):
    app = MechanismApp(server, sync=True, scene="iftomm-a01")
    try:
        view = app.system_view
        assert not view.forces.declared and view.force_panel is None
        assert "forces" not in dict(view.plots) and "forces" not in app.traj.plots
        assert not any(
            title == TITLE for (kind, _), h in app.plot_handles.items() if kind == app.kind for title in [h.title]
        )
    finally:
        app.close()
