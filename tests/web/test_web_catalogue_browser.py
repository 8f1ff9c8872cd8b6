"""Each catalogue system (and a plugged-in one) in headless Chromium: one browser, one app,
one page per system; the 3D view is not blank and differs from the other systems'."""

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest

from tests._helpers import require_browser
from web.screenshot import CHROMIUM_ARGS, close_toasts, open_page

CHROMIUM, sync_playwright = require_browser()

from nmkane_core.run.plugins import load_systems
from web.app import launch

pytestmark = pytest.mark.browser
SYSTEMS = ("knife-edge", "chaplygin-sleigh", "rolling-disk", "odometer-puck", "isokinetic-bowl")
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "isokinetic_bowl.py"
SHOTS = os.environ.get("NMKANE_SHOTS")  # a folder: keep the screenshots to look at


def _png(data: bytes) -> np.ndarray:
    from matplotlib.image import imread

    return imread(io.BytesIO(data), format="png")[..., :3]


def _colored(img: np.ndarray) -> np.ndarray:
    return np.abs(img - img.mean(axis=2, keepdims=True)).max(axis=2) > 0.15


def _drawn(img: np.ndarray) -> bool:
    """More than the grey ground plane is visible."""
    return bool(_colored(img).mean() > 0.002)


def test_each_system_is_drawn_and_recognizably_different(tmp_path):
    assert load_systems([str(EXAMPLE)]) == []
    app = launch(port=0)
    shots = {}
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            try:
                for name in SYSTEMS:
                    page = open_page(browser, app.url + "?hideViserLogo", width=1100, height=700)
                    with app._lock:
                        session = list(app.sessions.values())[-1]
                    title = next(t for t, n in session.choices.items() if n == name)
                    session.scene_choice.value = title
                    assert session.wait_idle(60)
                    page.wait_for_function(f"() => document.body.innerText.includes({session.system_view.folder!r})")
                    session.set_playing(False)
                    session.seek(1.0)
                    time.sleep(2.0)  # the camera and the nodes arrive
                    close_toasts(page)
                    cam = session.client.camera  # the browser shows the framing we sent
                    view = session.system_view
                    want = view.camera_target(None, "") + session.camera.offset
                    np.testing.assert_allclose(cam.position, want, atol=1e-3 * (1 + np.linalg.norm(want)))
                    np.testing.assert_allclose(session.camera.offset, view.camera_offset(None, ""), atol=1e-6)
                    deadline = time.monotonic() + 60  # a loaded machine: the nodes may arrive late
                    while True:
                        data = page.screenshot(timeout=120000)
                        if _drawn(_png(data)[:, :650]) or time.monotonic() > deadline:
                            break
                        time.sleep(0.5)
                    if SHOTS:
                        Path(SHOTS, f"{name}.png").write_bytes(data)
                    text = page.inner_text("body")
                    assert "Energy drift" in text and "Fit view" in text
                    shots[name] = _png(data)[:, :650]  # the 3D view left of the control panel
                    page.close()
            finally:
                browser.close()
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
