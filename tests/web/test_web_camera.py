"""The camera shows the motion (the teacher's item 4; issue 43 item 2), without a browser:
framing puts a box whole in the part of the canvas the panel leaves free; every system's first
view shows its whole mechanism, large, at every time of its run (fixed on the parts' whole
motion, or following them when that would show them much smaller); Fit view frames the
mechanism at the shown time, not the paths it traced; following translates without turning;
the keys step, fit and reset (tests/web/test_first_view_browser.py measures the drawn page)."""

import math

import numpy as np
import pytest

from nmkane_core import system_names
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


@pytest.fixture()
def app(module_server):
    a = MechanismApp(module_server, sync=True)
    yield a
    a.close()


def choose(app, name):
    app.scene_choice.value = next(t for t, n in app.choices.items() if n == name)


def _corners(box):
    lo, hi = box
    return [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]


def _shown(app, vp: Viewport, box) -> tuple[bool, float]:
    """Whether the box is whole in the part of the canvas the panel leaves free, seen by the
    camera as the app last placed it (following: where it follows to now), and how much of the
    free part's smaller side it spans."""
    view = app.system_view
    look, pos = app.camera.placed
    if app.follow.value:
        look = view.follow_target()
        pos = look + view.plan.offset
    px = _project(look, pos, _corners(box), vp)
    free = vp.width - PANEL_PX
    inside = (
        px[:, 0].min() >= -1 and px[:, 0].max() <= free + 1 and px[:, 1].min() >= -1 and px[:, 1].max() <= vp.height + 1
    )
    return bool(inside), float(max(np.ptp(px[:, 0]), np.ptp(px[:, 1])) / min(free, vp.height))


#: the least share of the free part's smaller side a first view's parts span (the browser test's)
LARGE = 0.12


@pytest.mark.parametrize("name", system_names())
def test_every_first_view_shows_the_whole_mechanism_large_at_every_time(app, name):
    """Before: Appell–Hamel's first view followed its wheel close up (the frame's legs and the
    pulleys off screen), the knife edge's blade was 11 % of the view at the edge of its circle."""
    choose(app, name)
    vp = Viewport()
    view = app.system_view
    app.reset_view()
    inside, span = _shown(app, vp, view.declared.parts_at(0))
    assert inside and span >= LARGE, f"{name} at t = 0: inside {inside}, spans {span:.0%}"
    for f in (0.25, 0.5, 0.75, 1.0):  # and it stays in view, fixed or following
        app.seek(f * app.traj.t_end)
        inside, span = _shown(app, vp, view.declared.parts_at(view.k))
        assert inside, f"{name} at t = {app.t_now:g}: the mechanism left the view (spans {span:.0%})"


@pytest.mark.parametrize(
    "name,follows",
    [
        ("knife-edge", True),
        ("chaplygin-sleigh", True),
        ("appell-hamel", True),
        ("odometer-puck", False),
        ("iftomm-a01", False),
        ("sliding-particle", False),
    ],
)
def test_the_first_view_follows_only_when_a_fixed_one_shows_the_mechanism_much_smaller(app, name, follows):
    choose(app, name)
    view = app.system_view
    assert view.plan.follows is follows and bool(app.follow.value) is follows
    app.seek(0.6 * app.traj.t_end)
    app.fit()
    assert bool(app.follow.value) is follows  # Fit view keeps following (or not)
    inside, span = _shown(app, Viewport(), view.declared.parts_at(view.k))
    assert inside, f"Fit view: the mechanism is not whole in view (spans {span:.0%})"
    framed = _shown(app, Viewport(), view.declared.mechanism_at(view.k))[1]  # (a particle: with its surface)
    assert framed > 0.5, f"Fit view frames the mechanism at {framed:.0%} of the view"
    app.reset_view()
    assert bool(app.follow.value) is follows


def test_fit_view_frames_the_mechanism_not_the_path_it_traced(app):
    """Before, Fit view framed every path of the run: the chaplygin sleigh's 24 m track made the
    1.5 m sleigh a few pixels; now it frames the sleigh where it is, from the side the viewer
    looks from."""
    choose(app, "chaplygin-sleigh")
    view = app.system_view
    app.seek(15.0)
    app.follow.value = False  # held: the camera stays where it is
    app.fit()
    vp = Viewport()
    inside, span = _shown(app, vp, view.declared.parts_at(view.k))
    assert inside and span > 0.5
    assert not _shown(app, vp, view.declared.bounds())[0] or _shown(app, vp, view.declared.bounds())[1] < 0.9


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
    app.follow.value = False
    cmds["f"]._impl.trigger_cb[0](None)
    assert not app.follow.value  # Fit view leaves the box as it is
    cmds["r"]._impl.trigger_cb[0](None)
    assert app.follow.value  # the Appell–Hamel first view follows the mechanism
