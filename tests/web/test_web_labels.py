"""Labels a class reads (issue 43, item 6): folder titles on one line."""

from __future__ import annotations

import numpy as np
import pytest

from tests._helpers import require
from tests.web._pages import covering, label_boxes

require("viser")


def test_every_catalogue_folder_label_fits_on_one_line():
    """viser draws a folder's label over the folder's top border: a label that wraps covers the
    folder's first line ("Simulation: Puck with an odometer flywheel (nonlinear constraint)",
    65 characters, did); 46 characters fit in the panel (measured in headless Chromium)."""
    from nmkane_core import get_system, system_names
    from web.generic import FOLDER_CHARS, folder_label

    labels = {n: folder_label(get_system(n).title or n) for n in system_names()}
    assert all(len(v) <= FOLDER_CHARS for v in labels.values()), labels
    assert labels["odometer-puck"] == "Simulation: Puck with an odometer flywheel"
    assert labels["appell-hamel"] == "Simulation: Appell–Hamel mechanism (Example 1)"  # fits: kept whole


@pytest.mark.parametrize(
    ("title", "label"),
    [
        ("Short one (kept)", "Simulation: Short one (kept)"),
        ("IFToMM A03: Andrews' squeezing mechanism", "Simulation: IFToMM A03: Andrews' squeezing…"),
        ("x" * 80, "Simulation: " + "x" * 33 + "…"),
    ],
)
def test_a_long_title_loses_its_parenthesis_then_its_last_words(title, label):
    from web.generic import FOLDER_CHARS, folder_label

    assert folder_label(title) == label and len(label) <= FOLDER_CHARS


# --------------------------------------------------------------------------- 3D labels apart
class _Label:
    """A stand-in for viser's label handle: its text and the corner it holds."""

    def __init__(self, text: str, anchor: str = "bottom-left"):
        self.text, self.anchor, self.sets = text, anchor, 0

    def __setattr__(self, name, value):
        if name == "anchor" and "anchor" in self.__dict__:
            self.__dict__["sets"] += 1
        super().__setattr__(name, value)


def _view(position=(10.0, 0.0, 0.0), look_at=(0.0, 0.0, 0.0)):
    from web.camera import Viewport
    from web.labels import seen_from

    return seen_from(look_at, position, Viewport(1280.0, 800.0))


def test_projection_puts_the_look_at_point_in_the_middle_and_up_up():
    v = _view()
    xy, front = v.project(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], [20.0, 0.0, 0.0]]))
    assert xy[0] == pytest.approx([640.0, 400.0])
    assert xy[1][1] < 400.0 and xy[1][0] == pytest.approx(640.0)  # above: higher on the screen
    assert xy[2][0] < 640.0  # seen from +x, −y is to the left
    assert list(front) == [True, True, True, False]  # behind the camera


def test_labels_at_one_point_take_the_four_corners():
    from web.labels import ANCHORS, LabelLayout

    labels = [_Label(t) for t in ("load P", "thread 9.53 N", "pulleys", "contact 5.4 N")]
    items = [(n, np.zeros(3)) for n in labels]
    assert covering(label_boxes(items, _view()))  # all bottom-left: each covers the others
    LabelLayout().apply(items, _view())
    assert len({n.anchor for n in labels}) == 4 and covering(label_boxes(items, _view())) is None
    assert labels[0].anchor == ANCHORS[0]  # the first keeps its preferred corner


def test_the_first_label_keeps_its_corner_and_nobody_hops_when_nothing_moves():
    from web.labels import LabelLayout

    a, b = _Label("load P"), _Label("thread 9.53 N")
    items = [(a, np.zeros(3)), (b, np.array([0.0, 0.0, 0.02]))]  # 2 cm apart, seen from 10 m
    layout = LabelLayout()
    assert layout.apply(items, _view()) == 1 and a.anchor == "bottom-left" and b.anchor != "bottom-left"
    assert layout.apply(items, _view()) == 0 and a.sets == 0 and b.sets == 1
    far = [(a, np.zeros(3)), (b, np.array([0.0, 0.0, 5.0]))]  # apart: b keeps the corner it has
    assert layout.apply(far, _view()) == 0
    assert layout.apply(items, None) == 0  # no camera reported yet: nothing changes


def test_when_every_corner_is_covered_the_least_covered_one_is_taken():
    from web.labels import choose

    xys = np.zeros((5, 2))
    out = choose(xys, ["a" * 10] * 4 + ["b"], ["bottom-left"] * 5)
    assert len(set(out[:4])) == 4 and out[4] in out[:4]


def test_the_page_keeps_the_paper_examples_labels_apart(server):
    """Appell–Hamel seen from its first view: at t = 0 the load hangs just under the pulleys, at
    t = 19 s the thread's force label sits at the load; their labels covered each other (issue
    43, item 6).  The layout, given the first view's camera, keeps every label's box apart."""
    from web.app import MechanismApp

    app = MechanismApp(server, sync=True)
    try:
        assert app.kind == "appell-hamel"
        view = app.system_view
        look_at, position = view.camera_plan().motion
        cam = _view(position, look_at)
        app.camera.view = lambda: cam  # the browser's camera (a test's app has no browser)
        for t in (0.0, 19.0):
            app.seek(t)  # a frame: the layout runs with the poses
            items = view.label_points()
            texts = sorted(n.text.split(" ")[0] for n, _ in items)
            assert texts == ["contact", "load", "pulleys", "thread", "wheel"], texts
            assert covering(label_boxes(items, cam)) is None, t
        assert app.playback.labels.changes > 0
    finally:
        app.close()


def test_two_labels_side_by_side_do_not_touch_when_another_corner_is_free():
    """ "thread 9.24 N" ending 1 px before "load P" on the same line reads as one text: a label
    leaves a corner where it only touches another for a free one."""
    from web.labels import GAP_PX, box, choose, overlap

    xys = np.array([[100.0, 100.0], [99.0, 100.0]])
    texts = ["load P", "thread 9.24 N"]
    picked = choose(xys, texts, ["bottom-left", "bottom-right"])
    a, b = (box(xy, t, k) for xy, t, k in zip(xys, texts, picked, strict=True))
    assert picked[0] == "bottom-left" and picked[1] != "bottom-right"
    assert overlap(a, b, GAP_PX) == 0.0
    before = box(xys[0], texts[0], "bottom-left"), box(xys[1], texts[1], "bottom-right")
    assert overlap(*before) == 0.0 and overlap(*before, GAP_PX) > 0.0  # it only touched


def test_the_ghosts_names_are_kept_apart_from_the_shown_runs_labels(server):
    """The sliding particle opens with two ghosts (its showcase): their names ride above their
    balls, among the normal force's label."""
    from web.app import MechanismApp

    app = MechanismApp(server, sync=True, scene="sliding-particle")
    try:
        view = app.system_view
        look_at, position = view.camera_plan().motion
        cam = _view(position, look_at)
        app.camera.view = lambda: cam
        for t in (0.0, 135.0, 290.0):
            app.seek(t)
            items = view.label_points()
            texts = [n.text for n, _ in items]
            assert sum("ghost:" in x for x in texts) == 2 and any(x.startswith("normal") for x in texts), texts
            assert covering(label_boxes(items, cam)) is None, t
    finally:
        app.close()
