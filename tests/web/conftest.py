"""The browser tests' Chromium: one headless Chromium (Debian's, driven by Playwright) for the
whole run, started by the first test that asks for ``browser`` and closed at the end
(tests/web/_pages.py: helpers that wait for what the page shows, never for a fixed time)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def _chromium():
    from tests._helpers import require_browser
    from web.screenshot import CHROMIUM_ARGS

    chromium, sync_playwright = require_browser()  # skipped off CI without it, an error under CI=true
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
        yield browser
        browser.close()


@pytest.fixture
def browser(_chromium):
    """The shared Chromium; the pages a test leaves open are closed after it (each page has a
    browser context of its own: nothing carries over from one test to the next)."""
    yield _chromium
    for context in list(_chromium.contexts):
        context.close()
