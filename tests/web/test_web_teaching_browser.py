"""The teacher's page in headless Chromium: what is typed in the boxes is what the run uses
(or is refused beside the box), a link reopens its setup in a fresh browser, the keys work,
and the plots show values at the cursor and keep a zoom.  Waits are deadlines on the page's
or the session's state, never fixed sleeps; the run's one Chromium (tests/web/conftest.py)."""

import itertools
import re
import time

import numpy as np
import pytest

from tests._helpers import require_browser
from tests.web._pages import until
from web.chromium import POLL_MS
from web.screenshot import close_toasts, input_of, open_page

require_browser()

from web.app import launch

pytestmark = pytest.mark.browser


@pytest.fixture(scope="module")
def app():
    handle = launch(port=0)
    yield handle
    handle.stop()


def _session(app, before: set, name: str | None = None):
    """The session of the page just opened (its system installed, if one is named)."""
    found = []

    def ready():
        found[:] = [s for cid, s in list(app.sessions.items()) if cid not in before]
        s = found[0] if found else None
        return s is not None and s.traj is not None and (name is None or s.traj.kind == name)

    until(ready, 120, f"the new page's session ({name})")
    assert found[0].wait_idle(60)
    return found[0]


def _open(app, browser, query: str = "", name: str | None = None, context=None):
    before = set(app.sessions)
    page = (context or browser).new_page(viewport={"width": 1400, "height": 900}) if context else None
    if page is None:
        page = open_page(browser, app.url + "?hideViserLogo" + query)
    else:
        page.goto(app.url + "?hideViserLogo" + query)
        page.wait_for_function("() => document.body.innerText.includes('update ')", timeout=60000, polling=POLL_MS)
    close_toasts(page)
    return page, _session(app, before, name)


def _retry(action, timeout: float = 120.0):
    """A page action, again while its element is being rebuilt (a chart, under load)."""
    from playwright.sync_api import Error

    end = time.monotonic() + timeout
    while True:
        try:
            return action()
        except Error:
            if time.monotonic() > end:
                raise
            time.sleep(0.1)


TIP_SHOWS_DE = (
    "() => { const t = document.querySelector('.nmk-tip'); return t && t.style.display === 'block' "
    "&& t.textContent.includes('ΔE') && /\\d/.test(t.textContent); }"
)


def _hover(page, plot, over, shown: str, timeout: float = 120.0) -> dict:
    """Point at the middle of a plot until ``shown`` (a page predicate) holds; the plot's box.
    The pointer moves again each try, onto the box as it is then: the page's plot script may
    arrive after the first move, and under load the panel can still move (content arriving
    above the plot) between reading the box and moving — a single move then hovers nothing."""
    from playwright.sync_api import TimeoutError as PlaywrightTimeout

    page.wait_for_function("() => window.__nmkPlots === true", timeout=60000, polling=POLL_MS)
    end = time.monotonic() + timeout
    for k in itertools.count():
        _retry(lambda: plot.scroll_into_view_if_needed(timeout=30000))
        box = _retry(lambda: over.bounding_box(timeout=30000))
        nudge = (k % 5 - 2) * 0.02  # a new position each try: a move to where the pointer is fires nothing
        page.mouse.move(box["x"] + (0.5 + nudge) * box["width"], box["y"] + 0.5 * box["height"])
        try:
            page.wait_for_function(shown, timeout=3000, polling=POLL_MS)
            return box
        except PlaywrightTimeout:
            if time.monotonic() > end:
                raise
    raise AssertionError("unreachable")


def _type(page, label: str, text: str) -> None:
    box = input_of(page, label)
    _retry(lambda: box.fill(text, timeout=30000))
    box.press("Enter")


def _type_exact(page, label: str, text: str) -> None:
    """As _type, for a label that others contain (``M [kg]`` beside ``m [kg]``)."""
    row = page.locator("label").filter(has_text=re.compile(f"^{re.escape(label)}$")).first
    box = row.locator("xpath=ancestor::div[contains(@class, 'Flex-root')][1]").locator("input").last
    _retry(lambda: box.fill(text, timeout=30000))
    box.press("Enter")


def _shown(session):
    return session.traj.request["settings"]


#: what is typed in the page's boxes, one after the other in one page (a page takes ~7 s to
#: open in software-drawn Chromium: one page per value made five tests of 15–17 s each)
TYPED = (
    ("Δt [s]", "1e-3", ("dt",), 0.001),
    ("Γ (nonholonomic)", "-1e1", ("gamma",), -10.0),
    ("Final time [s]", "2.5E+1", ("t_final",), 25.0),
    ("u1 = θ̇", "5e-1", ("initial", "u1"), 0.5),
    ("u2 = φ̇", "0.001", ("initial", "u2"), 0.001),
)


def test_what_is_typed_in_the_page_is_what_the_run_uses(app, browser):
    page, session = _open(app, browser, name="appell-hamel")
    try:
        for label, text, field, value in TYPED:
            _type(page, label, text)

            def used(field=field, value=value):
                s = _shown(session)
                return (s[field[0]] if len(field) == 1 else s[field[0]][field[1]]) == value

            until(used, 30, f"{label} = {text} in the run")
            assert "input refused" not in page.inner_text("body"), f"{label} = {text}"
    finally:
        page.close()


def test_what_cannot_be_read_is_refused_beside_the_box_in_the_page(app, browser):
    page, session = _open(app, browser, name="appell-hamel")
    try:
        before = dict(_shown(session))
        for label, text, why in (
            ("u1 = θ̇", "1,5", "write the decimal point as a point (1.5)"),
            ("Γ (nonholonomic)", "1e9", "1e9 is outside the allowed range -50 … 10 1/s"),
            ("Final time [s]", "abc", "'abc' is not a number"),
        ):
            _type(page, label, text)
            page.wait_for_function(
                "(w) => Array.from(document.querySelectorAll('.nmk-msg')).some((m) => m.innerText.includes(w))",
                arg=why,
                timeout=30000,
                polling=POLL_MS,
            )
        assert session.wait_idle(30) and _shown(session) == before  # nothing ran with a refused value
        page.get_by_text("Physical parameters", exact=True).first.click()  # a log slider's box, in kg
        _type_exact(page, "M [kg]", "1e1")
        until(lambda: _shown(session)["params"]["M"] == 10.0, 30, "M = 10 kg in the run")
        _type(page, "Final time [s]", "7")  # good again: its message goes
        until(lambda: _shown(session)["t_final"] == 7.0, 30, "t_final = 7")
        page.wait_for_function(
            "() => !Array.from(document.querySelectorAll('.nmk-msg')).some((m) => m.innerText.includes('abc'))",
            timeout=30000,
            polling=POLL_MS,
        )
    finally:
        page.close()


def test_a_link_reopens_its_setup_in_a_fresh_browser(app, browser):
    query = "&system=rolling-disk&dt=0.002&t_final=7&params.r=0.25&initial.u4=0.5&gamma=-10"
    page, session = _open(app, browser, query, name="rolling-disk")
    try:
        s = _shown(session)
        assert (s["dt"], s["t_final"], s["gamma"], s["params"]["r"], s["initial"]["u4"]) == (0.002, 7, -10, 0.25, 0.5)
        _type(page, "u3 = ψ̇", "-1")  # a change: the address follows
        # the whole value: "initial.u3=-1" is also the start of "initial.u3=-1.5" (a CI-like run
        # went on before the typed -1 was in the address)
        page.wait_for_function(
            "() => /[?&]initial\\.u3=-1(&|$)/.test(window.location.search)", timeout=30000, polling=POLL_MS
        )
        link = page.url
        assert "system=rolling-disk" in link and "params.r=0.25" in link and "hideViserLogo" in link
        page.get_by_role("button", name="Copy link").click()
        until(lambda: session.link.copied == link, 30, "the copied link")
    finally:
        page.close()
    fresh = browser.new_context(viewport={"width": 1400, "height": 900})  # no cookies, no storage
    try:
        before = set(app.sessions)
        page = fresh.new_page()
        page.goto(link)
        again = _session(app, before, "rolling-disk")
        until(lambda: _shown(again).get("initial", {}).get("u3") == -1.0, 60, "the link's values")
        s = _shown(again)
        assert (s["dt"], s["t_final"], s["gamma"], s["params"]["r"], s["initial"]["u4"]) == (0.002, 7, -10, 0.25, 0.5)
        assert input_of(page, "u3 = ψ̇").input_value() == "-1"
        page.reload()  # state survives a reload
        third = _session(app, set(app.sessions) - {again.client.client_id}, "rolling-disk")
        until(lambda: _shown(third).get("initial", {}).get("u3") == -1.0, 60, "the setup after a reload")
    finally:
        fresh.close()


def test_keys_play_step_and_fit_and_the_plots_show_values_and_keep_a_zoom(app, browser):
    page, session = _open(app, browser, name="appell-hamel")
    try:
        page.mouse.click(300, 450)  # the canvas has the focus, not a box
        assert session.playing
        page.keyboard.press(" ")
        until(lambda: not session.playing, 10, "space to pause")
        t = session.t_now
        page.keyboard.press("ArrowRight")
        until(lambda: session.t_now > t, 10, "→ to step")
        assert session.follow.value
        placed = session.camera.placed
        page.keyboard.press("f")
        until(lambda: session.camera.placed is not placed, 10, "f to fit the mechanism as it is now")
        assert session.follow.value  # and the camera goes on following it
        assert "space play/pause" in page.inner_text("body")

        plot = page.locator(".uplot").filter(has_text="Energy drift").first
        over = plot.locator(".u-over")
        box = _hover(page, plot, over, TIP_SHOWS_DE)
        until(lambda: session.plots.busy, 10, "the page to report the pointer on a plot")
        page.mouse.move(box["x"] + 0.2 * box["width"], box["y"] + 0.5 * box["height"])
        page.mouse.down()
        page.mouse.move(box["x"] + 0.6 * box["width"], box["y"] + 0.5 * box["height"], steps=6)
        page.mouse.up()
        page.mouse.move(10, 10)  # away from the plot: still busy (zoomed), the marker waits
        until(lambda: session.plots.busy, 10, "a zoomed plot to keep the marker waiting")
        axes = session.plot_handles[("appell-hamel", "energy")].axes
        session.seek(session.t_now + 1.0)
        assert session.plot_handles[("appell-hamel", "energy")].axes == axes
        _retry(lambda: over.dblclick(timeout=30000))
        page.mouse.move(10, 10)
        until(lambda: not session.plots.busy, 10, "double-click to zoom out")
        assert np.isfinite(session.t_now)
    finally:
        page.close()
