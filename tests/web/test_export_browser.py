"""The exported page in a real browser, from file:// with the network off: the scene draws,
the playback bar plays and scrubs the recorded motion, the plots follow it, and nothing but
the file itself is requested (headless Chromium, the Debian package, driven by Playwright)."""

import pytest

from tests._helpers import require_browser
from tests.web._pages import until

require_browser()

import nmkane_core
from web import export
from web.chromium import POLL_MS
from web.screenshot import close_toasts

pytestmark = pytest.mark.browser

AH = "appell-hamel"
BODY = (
    "(() => { const m = window.__viserMutable; const n = m && m.nodeRefFromName['/sys/appell-hamel/frames/body'];"
    " return n ? n.position.toArray() : null })()"
)
BAR_TIME = "parseFloat(document.querySelector('[role=slider][aria-valuenow]').getAttribute('aria-valuenow'))"
CURSOR_LEFT = "parseFloat(document.querySelector('#nmk-panel .nmk-cursor').style.left)"


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    run = nmkane_core.simulate({"system": AH, "t_final": 6.0, "dt": 0.01}, progress=False)
    return export.write(run, tmp_path_factory.mktemp("export") / "run.html")


@pytest.fixture
def offline_page(browser, exported):
    """The exported file opened with the network off; every request the page makes that is not
    the file itself (or data it holds: data:, blob:) is aborted and recorded."""
    context = browser.new_context(viewport={"width": 1400, "height": 850})
    context.set_offline(True)
    outside: list[str] = []

    def guard(route):
        url = route.request.url
        if url.startswith(("file:", "data:", "blob:")):
            route.continue_()
        else:
            outside.append(url)
            route.abort()

    context.route("**/*", guard)
    requested: list[str] = []
    page = context.new_page()
    page.on("request", lambda r: requested.append(r.url))
    page.goto(exported.as_uri())
    page.wait_for_function(
        f"() => !!document.querySelector('canvas[data-engine]') && !!{BODY}", timeout=60000, polling=POLL_MS
    )
    close_toasts(page)
    yield page, outside, requested
    context.close()


def _scrub(page, bar, fraction: float) -> None:
    """Click the playback bar ``fraction`` along it, at its box as it is now (a run under CI
    load missed the cursor moving after a click at a box read earlier; the box was stable in
    the runs looked at since, so this only rules that cause out)."""
    box = bar.bounding_box()
    page.mouse.click(box["x"] + fraction * box["width"], box["y"] + box["height"] / 2)


def test_the_exported_page_plays_and_scrubs_offline_with_its_plots(offline_page):
    page, outside, requested = offline_page
    # the scene: a WebGL canvas of the page's size, the declared bodies in the scene tree
    size = page.evaluate(
        "(() => { const c = document.querySelector('canvas[data-engine]'); return [c.width, c.height] })()"
    )
    assert size[0] > 800 and size[1] > 500
    # playback advances: the bar's time changes and the body moves
    t0, p0 = page.evaluate(BAR_TIME), page.evaluate(BODY)
    # (changing, not growing: the 6 s recording loops, and a slow load may find it near its end)
    until(lambda: abs(page.evaluate(BAR_TIME) - t0) > 0.5, 60, "the playback bar advancing")
    until(lambda: page.evaluate(BODY) != p0, 60, "the body moving")
    # pause, then scrub by clicking three quarters along the bar
    bar = page.locator(".mantine-Slider-root")
    bar.locator("xpath=ancestor::div[.//button][1]").locator("button").first.click()  # ❚❚
    paused = page.evaluate(BAR_TIME)
    page.wait_for_timeout(400)  # a paused bar stays where it is
    assert page.evaluate(BAR_TIME) == pytest.approx(paused, abs=1e-9)
    _scrub(page, bar, 0.75)
    until(lambda: abs(page.evaluate(BAR_TIME) - 4.5) < 0.4, 10, "the bar scrubbed to 3/4 of 6 s")
    at_scrub = page.evaluate(BODY)
    _scrub(page, bar, 0.2)
    until(lambda: abs(page.evaluate(BAR_TIME) - 1.2) < 0.4, 10, "the bar scrubbed to 1/5 of 6 s")
    until(lambda: page.evaluate(BODY) != at_scrub, 10, "the body moved by scrubbing")
    # the plots: energy drift and violation drawn, their cursor at the bar's time
    titles = page.eval_on_selector_all("#nmk-panel .nmk-plot", "els => els.map(e => e.dataset.plot)")
    assert titles[:2] == ["Energy drift ΔE(t)", "log₁₀ |constraint violation|"]
    assert page.locator("#nmk-panel .nmk-plot svg").count() == len(titles)
    until(lambda: abs(float(page.inner_text("#nmk-time")) - page.evaluate(BAR_TIME)) < 0.05, 10, "the panel's time")
    left_early = page.evaluate(CURSOR_LEFT)
    _scrub(page, bar, 0.9)
    until(lambda: abs(page.evaluate(BAR_TIME) - 5.4) < 0.4, 10, "the bar scrubbed to 9/10 of 6 s")
    # (the cursor's left is a percentage of the plot's width: 1.2 s → 5.4 s moves it by ~60)
    until(
        lambda: page.evaluate(CURSOR_LEFT) > left_early + 20,
        10,
        f"the plot cursor following the bar (from {left_early:.1f} % at {page.evaluate(BAR_TIME):.2f} s)",
    )
    # nothing but the file was asked for
    assert outside == []
    assert all(u.startswith(("file:", "data:", "blob:")) for u in requested), requested


def test_the_pages_export_button_downloads_the_run_on_screen(browser, tmp_path):
    from web.app import launch
    from web.screenshot import open_page

    app = launch(port=0, scene=AH)
    try:
        page = open_page(browser, app.url + "?hideViserLogo")
        assert app.wait_for_session().wait_idle(60)
        button = page.get_by_role("button", name="Export run (offline HTML)")
        with page.expect_download(timeout=60000) as info:
            button.click()
        download = info.value
        assert download.suggested_filename.startswith(f"{AH}-") and download.suggested_filename.endswith(".html")
        saved = tmp_path / download.suggested_filename
        download.save_as(saved)
        text = saved.read_text(encoding="utf-8")
        assert "window.__VISER_EMBED_DATA__=" in text and 'data-system="appell-hamel"' in text
    finally:
        app.stop()


def test_export_to_gif_films_the_page_frame_by_frame(tmp_path):
    import numpy as np
    from PIL import Image

    from web import export_gif

    run = nmkane_core.simulate({"system": AH, "t_final": 0.5, "dt": 0.01}, progress=False)
    out = export_gif.write_gif(run, tmp_path / "run.gif")
    assert [p.name for p in tmp_path.iterdir()] == ["run.gif"]  # no partial file left
    with Image.open(out) as gif:
        assert gif.n_frames == 6 and gif.size == export_gif.SIZE  # 10 per second of playback, both ends
        assert gif.info["duration"] == 100
        first = np.asarray(gif.convert("RGB"), float)
        gif.seek(gif.n_frames - 1)
        last = np.asarray(gif.convert("RGB"), float)
    assert np.abs(first - last).mean() > 0.5  # the mechanism moved (and the plot cursor)
