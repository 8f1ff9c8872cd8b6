"""The Whipple bicycle in headless Chromium: its declared scene is drawn (not blank, coloured
parts), its sliders are the declared ones, and the eigenvalue plot of its stability sweep is
on the page with data (NMKANE_SHOTS=folder keeps the screenshot)."""

import os
from pathlib import Path

import numpy as np
import pytest

from tests._helpers import require_browser
from tests.web._pages import HIDE_TOASTS, new_session, png, settled, until
from web.chromium import POLL_MS
from web.screenshot import close_toasts, open_page

require_browser()

from web.app import launch

pytestmark = pytest.mark.browser
SHOTS = os.environ.get("NMKANE_SHOTS")


def test_bicycle_scene_sliders_and_eigenvalue_plot(browser):
    app = launch(port=0)
    try:
        session, page = new_session(app, lambda: open_page(browser, app.url + "?hideViserLogo", width=1300, height=900))
        title = next(t for t, n in session.choices.items() if n == "whipple-bicycle")
        session.scene_choice.value = title
        assert session.wait_idle(300)
        page.wait_for_function(
            f"() => document.body.innerText.includes({session.system_view.folder!r})", polling=POLL_MS
        )
        session.set_playing(False)
        session.seek(1.0)
        view = session.system_view
        plot = view.stability_plot
        until(lambda: len(plot.handle.data[0]) >= 100, 120, "the eigenvalue plot has no data")
        assert len(plot.handle.data[0]) == 101 and len(plot.handle.data) == 6  # speeds, 4 Re, max Im
        assert plot.value == pytest.approx(5.0)  # the default run's speed is marked
        page.wait_for_function("() => document.body.innerText.includes('Eigenvalues against speed')", polling=POLL_MS)
        close_toasts(page)
        shoot = lambda: page.screenshot(timeout=120000, style=HIDE_TOASTS)  # noqa: E731
        until(lambda: _drawn(png(shoot())[:, :700]), 60, "nothing but the ground plane is visible")
        img = settled(shoot)[:, :700]  # the nodes arrived, nothing moves any more
        if SHOTS:
            Path(SHOTS, "whipple-bicycle.png").write_bytes(shoot())
        text = page.inner_text("body")
        assert "Eigenvalues against speed" in text
        assert "q4 (roll) [rad]" in text and "u6 = q̇6 (rear wheel rate" in text
        assert "q8(0)" not in text  # only the declared initial values get sliders
    finally:
        app.stop()
    assert img.mean(axis=2).std() > 0.03, "the 3D view is blank"
    assert _drawn(img), "nothing but the ground plane is visible"


def _drawn(img: np.ndarray) -> bool:
    colored = np.abs(img - img.mean(axis=2, keepdims=True)).max(axis=2) > 0.15
    return bool(colored.mean() > 0.002)
