"""Each catalogue system (and a plugged-in one) in headless Chromium: one browser, one app, one
page whose Scene is switched to each system in turn (as a student does; a page opens on the
default system, so each one was reached by a switch before too); the 3D view is not blank and
differs from the other systems'."""

import os
from pathlib import Path

import numpy as np
import pytest

from tests._helpers import require_browser
from tests.web._pages import HIDE_TOASTS, new_session, png, settled, until
from web.screenshot import close_toasts, open_page

require_browser()

from nmkane_core.run.plugins import load_systems
from web.app import launch

pytestmark = pytest.mark.browser
SYSTEMS = ("knife-edge", "chaplygin-sleigh", "rolling-disk", "odometer-puck", "isokinetic-bowl")
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "isokinetic_bowl.py"
SHOTS = os.environ.get("NMKANE_SHOTS")  # a folder: keep the screenshots to look at


def _colored(img: np.ndarray) -> np.ndarray:
    return np.abs(img - img.mean(axis=2, keepdims=True)).max(axis=2) > 0.15


def _drawn(img: np.ndarray) -> bool:
    """More than the grey ground plane is visible."""
    return bool(_colored(img).mean() > 0.002)


def _look_at(session, page, name: str) -> tuple[np.ndarray, bytes]:
    """The page switched to ``name``, paused at t = 1 s, once the browser shows the framing the
    server sent and the scene is drawn: the 3D view left of the control panel, and the screenshot."""
    title = next(t for t, n in session.choices.items() if n == name)
    session.set_playing(True)  # a switch starts the new system playing, as on a fresh page
    session.scene_choice.value = title
    assert session.wait_idle(60)
    page.wait_for_function(f"() => document.body.innerText.includes({session.system_view.folder!r})")
    session.set_playing(False)
    session.seek(1.0)
    close_toasts(page)
    view = session.system_view
    want = view.camera_target(None, "") + session.camera.offset
    np.testing.assert_allclose(session.camera.offset, view.camera_offset(None, ""), atol=1e-6)
    cam = session.client.camera  # the browser shows the framing we sent: it reports its camera back
    tol = 1e-3 * (1 + np.linalg.norm(want))
    until(lambda: np.allclose(cam.position, want, rtol=0, atol=tol), 60, f"{name}: the camera sent is not shown")
    shoot = lambda: page.screenshot(timeout=120000, style=HIDE_TOASTS)  # noqa: E731
    until(lambda: _drawn(png(shoot())[:, :650]), 60, f"{name}: nothing but the grey ground plane is visible")
    img = settled(shoot)[:, :650]  # the nodes arrived (a loaded machine: late), nothing moves any more
    text = page.inner_text("body")
    assert "Energy drift" in text and "Fit view" in text
    return img, shoot()


def test_each_system_is_drawn_and_recognizably_different(browser):
    assert load_systems([str(EXAMPLE)]) == []
    app = launch(port=0)
    shots = {}
    try:
        session, page = new_session(app, lambda: open_page(browser, app.url + "?hideViserLogo", width=1100, height=700))
        for name in SYSTEMS:
            shots[name], data = _look_at(session, page, name)
            if SHOTS:
                Path(SHOTS, f"{name}.png").write_bytes(data)
        page.close()
    finally:
        app.stop()
    for name, img in shots.items():
        gray = img.mean(axis=2)
        assert gray.std() > 0.03, f"{name}: the 3D view is blank"
        assert _drawn(img), f"{name}: nothing but the grey ground plane is visible"
    names = list(shots)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            diff = np.abs(shots[a] - shots[b]).mean()
            assert diff > 0.01, f"{a} and {b} look the same ({diff:.4f})"
