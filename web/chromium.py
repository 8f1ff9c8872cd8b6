"""Headless Chromium for the web app's pictures and films: Debian's binary, the flags it runs
with, and closing software WebGL's notice (:mod:`web.screenshot`, :mod:`web.export_gif`, the
browser tests)."""

from __future__ import annotations

import os
import shutil

CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
]


def chromium_path() -> str | None:
    """The Chromium binary (Debian's package), or None."""
    found = shutil.which("chromium")
    if found:
        return found
    return "/usr/bin/chromium" if os.path.exists("/usr/bin/chromium") else None


CLOSE_BUTTONS = ".mantine-Notification-closeButton"
#: how often a page's condition is checked while waiting on it (ms): Playwright's default checks
#: once per animation frame, and a page drawn in software (SwiftShader) draws about one a second
POLL_MS = 50


def close_toasts(page) -> None:
    """Close the 'Software WebGL rendering detected' notification (headless SwiftShader).

    The close buttons get the click event itself: a pointer click waits until the page has
    drawn frames showing the button stable, and a page drawn in software takes a second or
    more per frame (2–3 s per page in the catalogue test)."""
    gone = f"(n) => document.querySelectorAll('{CLOSE_BUTTONS}').length < n"
    for _ in range(3):
        buttons = page.locator(CLOSE_BUTTONS)
        n = buttons.count()
        if n == 0:
            break
        try:
            buttons.first.dispatch_event("click", timeout=2000)
            page.wait_for_function(gone, arg=n, polling=POLL_MS, timeout=2000)
        except Exception:
            break
