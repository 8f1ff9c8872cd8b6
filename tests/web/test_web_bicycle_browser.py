"""The Whipple bicycle in headless Chromium: its declared scene is drawn (not blank, coloured
parts), its sliders are the declared ones, and the eigenvalue plot of its stability sweep is
on the page with data (NMKANE_SHOTS=folder keeps the screenshot)."""

import io
import os
import time
from pathlib import Path

import numpy as np
import pytest

from tests._helpers import require_browser
from web.screenshot import CHROMIUM_ARGS, close_toasts, open_page

CHROMIUM, sync_playwright = require_browser()

from web.app import launch

pytestmark = pytest.mark.browser
SHOTS = os.environ.get("NMKANE_SHOTS")


def test_bicycle_scene_sliders_and_eigenvalue_plot():
    from matplotlib.image import imread

    app = launch(port=0)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
            try:
                page = open_page(browser, app.url + "?hideViserLogo", width=1300, height=900)
                with app._lock:
                    session = list(app.sessions.values())[-1]
                title = next(t for t, n in session.choices.items() if n == "whipple-bicycle")
                session.scene_choice.value = title
                assert session.wait_idle(300)
                page.wait_for_function(f"() => document.body.innerText.includes({session.system_view.folder!r})")
                session.set_playing(False)
                session.seek(1.0)
                view = session.system_view
                plot = view.stability_plot
                deadline = time.time() + 120
                while time.time() < deadline and len(plot.handle.data[0]) < 100:
                    time.sleep(0.5)
                assert len(plot.handle.data[0]) == 101 and len(plot.handle.data) == 6  # speeds, 4 Re, max Im
                assert plot.value == pytest.approx(5.0)  # the default run's speed is marked
                time.sleep(2.0)
                close_toasts(page)
                data = page.screenshot(timeout=120000)
                if SHOTS:
                    Path(SHOTS, "whipple-bicycle.png").write_bytes(data)
                text = page.inner_text("body")
                assert "Eigenvalues against speed" in text
                assert "q4 (roll) [rad]" in text and "u6 = q̇6 (rear wheel rate" in text
                assert "q8(0)" not in text  # only the declared initial values get sliders
            finally:
                browser.close()
    finally:
        app.stop()
    img = imread(io.BytesIO(data), format="png")[..., :3][:, :700]
    assert img.mean(axis=2).std() > 0.03, "the 3D view is blank"
    colored = np.abs(img - img.mean(axis=2, keepdims=True)).max(axis=2) > 0.15
    assert colored.mean() > 0.002, "nothing but the ground plane is visible"
