"""Headless Chromium for the web app's pictures and films: Debian's binary, the flags it runs
with, and closing software WebGL's notice (:mod:`web.screenshot`, :mod:`web.export_gif`, the
browser tests)."""

from __future__ import annotations

import os
import shutil
import time

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


def close_toasts(page) -> None:
    """Close the 'Software WebGL rendering detected' notification (headless SwiftShader)."""
    for _ in range(3):
        buttons = page.locator(".mantine-Notification-closeButton")
        if buttons.count() == 0:
            break
        try:
            buttons.first.click(timeout=2000)
        except Exception:
            break
        time.sleep(0.2)
