"""The camera shows the motion (the teacher's item 4), without a browser: framing puts a box
whole in the part of the canvas the panel leaves free; Fit view frames every path of the
run and stops following; the first view follows only a motion much larger than the system,
and following translates without turning; the keys step, fit and reset."""

import math

import numpy as np
import pytest
import viser

from web.camera import PANEL_PX, Viewport, frame
from web.keys import STEP_FRAMES_S, step
from web.session import MechanismApp


def _project(look, pos, pts, vp: Viewport):
    """Pixel coordinates of world points for a camera at pos looking at look (z up)."""
    f = (look - pos) / np.linalg.norm(look - pos)
    right = np.cross(f, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    rel = np.asarray(pts, float) - pos
    depth = rel @ f
    t = math.tan(vp.fov / 2)
    x = (rel @ right) / depth / t * (vp.height / 2) + vp.width / 2
    y = -(rel @ up) / depth / t * (vp.height / 2) + vp.height / 2
    return np.column_stack([x, y])


@pytest.mark.parametrize("box", [((-2, -2, 0), (2, 2, 0.1)), ((0, 0, 0), (1, 5, 3)), ((-90, 0, 0), (0, 120, 1))])
@pytest.mark.parametrize("direction", [None, (0.0, -1.0, 0.3), (-0.5, 0.85, 0.3)])
def test_a_framed_box_is_whole_in_the_free_part_of_the_canvas(box, direction):
    vp = Viewport(1280, 800)
    look, pos = frame(box, direction, vp)
    lo, hi = (np.array(b, float) for b in box)
    corners = [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    px = _project(look, pos, corners, vp)
    assert px[:, 0].min() >= 0 and px[:, 0].max() <= vp.width - PANEL_PX + 1
    assert px[:, 1].min() >= 0 and px[:, 1].max() <= vp.height
    span = max(np.ptp(px[:, 0]) / (vp.width - PANEL_PX), np.ptp(px[:, 1]) / vp.height)
    assert span > 0.55  # and it fills the free part (not a few pixels)


@pytest.fixture(scope="module")
def server():
    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    yield srv
    srv.stop()


@pytest.fixture()
def app(server):
    a = MechanismApp(server, sync=True)
    yield a
    a.close()


def choose(app, name):
    app.scene_choice.value = next(t for t, n in app.choices.items() if n == name)


@pytest.mark.parametrize("name,follows", [("knife-edge", False), ("chaplygin-sleigh", True), ("appell-hamel", True)])
def test_the_first_view_follows_only_a_large_motion_and_fit_view_shows_it_whole(app, name, follows):
    choose(app, name)
    view = app.system_view
    assert view.plan.follows is follows and bool(app.follow.value) is follows
    app.fit()
    assert not app.follow.value  # fixed: else the camera would leave the whole-motion view
    lo, hi = view.declared.bounds()  # every path travelled …
    corners = [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    vp = Viewport()
    px = _project(*view.plan.whole, corners, vp)  # … inside the part of the canvas the panel leaves free
    assert px[:, 0].min() >= -1 and px[:, 0].max() <= vp.width - PANEL_PX + 1
    assert px[:, 1].min() >= -1 and px[:, 1].max() <= vp.height + 1
    app.reset_view()
    assert bool(app.follow.value) is follows


def test_following_translates_with_the_bodies_and_never_turns(app):
    choose(app, "chaplygin-sleigh")  # it spins: the camera must not
    view = app.system_view
    offsets = []
    for t in (0.5, 1.5, 3.0, 8.0):
        app.seek(t)
        offsets.append(view.plan.offset.copy())
        target = view.follow_target()
        assert np.allclose(target - view._centre(), view.plan.shift)
    assert all(np.allclose(o, offsets[0]) for o in offsets)


def test_the_keys_step_pause_fit_and_reset(app):
    app.seek(2.0)
    step(app, +1)
    assert not app.playing and app.t_now == pytest.approx(2.0 + STEP_FRAMES_S)
    step(app, -1)
    assert app.t_now == pytest.approx(2.0)
    cmds = app.keys
    assert set(cmds) == {"space", "left", "right", "f", "r"}
    cmds["space"]._impl.trigger_cb[0](None)
    assert app.playing
    cmds["f"]._impl.trigger_cb[0](None)
    assert not app.follow.value
    cmds["r"]._impl.trigger_cb[0](None)
    assert app.follow.value  # the Appell–Hamel first view follows the wheel
