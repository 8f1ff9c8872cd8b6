"""Screenshots of the web app in headless Chromium (Playwright driving the Debian binary).

    python -m web.screenshot [--out docs/screenshots] [--systems FILE ...] [NAME ...]

starts the app on a free port, opens one page per system (default: every registered
one), waits until the panel is filled, shows the motion at 45 % of its time with the
system's default camera and its simulation folder folded (the plots beside the scene), and
writes ``<out>/<NAME>.png``.  The e2e tests use the same helpers.
"""

from __future__ import annotations

import os
import time

from .chromium import CHROMIUM_ARGS, POLL_MS, chromium_path, close_toasts

__all__ = ["CHROMIUM_ARGS", "capture", "chromium_path", "close_toasts", "collapse", "input_of", "open_page"]


def open_page(
    browser, url: str, width: int = 1400, height: int = 900, timeout_ms: int = 60000, requests: list | None = None
):
    """A page connected to the app with its panel filled (the first trajectory installed);
    the URLs it requests are appended to ``requests``."""
    page = browser.new_page(viewport={"width": width, "height": height})
    if requests is not None:
        page.on("request", lambda r: requests.append(r.url))
    page.goto(url)
    page.wait_for_function(
        "() => !document.body.innerText.includes('Connecting...')", timeout=timeout_ms, polling=POLL_MS
    )
    page.wait_for_function("() => document.body.innerText.includes('update ')", timeout=timeout_ms, polling=POLL_MS)
    close_toasts(page)
    return page


def collapse(page, folder: str) -> None:
    """Fold a GUI folder by clicking its title."""
    page.get_by_text(folder, exact=True).first.click()


def input_of(page, label: str):
    """The number box next to a slider (or the box of a number input) with this label."""
    row = page.locator("label", has_text=label).first.locator("xpath=ancestor::div[contains(@class, 'Flex-root')][1]")
    return row.locator("input:not([type='hidden'])").last


def capture(out_dir: str = "docs/screenshots", names=None, fraction: float = 0.45) -> list[str]:
    """Screenshots of the systems ``names`` (default: every registered one) in ``out_dir``;
    each at ``fraction`` of its run's time.  Returns the files written."""
    from playwright.sync_api import sync_playwright

    from nmkane_core.run.registry import system_names

    from .app import launch

    exe = chromium_path()
    if exe is None:
        raise SystemExit("headless Chromium not found (apt-get install chromium)")
    os.makedirs(out_dir, exist_ok=True)
    app = launch(port=0)
    written = []
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
            try:
                for name in names or system_names():
                    page = open_page(browser, f"http://127.0.0.1:{app.port}/?hideViserLogo")
                    with app._lock:
                        session = list(app.sessions.values())[-1]
                    session.wait_idle(60)
                    title = next(t for t, n in session.choices.items() if n == name)
                    if session.scene_choice.value != title:
                        session.scene_choice.value = title
                    session.wait_idle(60)
                    time.sleep(1.0)
                    session.set_playing(False)
                    traj = session.traj
                    assert traj is not None  # wait_idle: the first run is installed
                    session.seek(fraction * traj.t_end)
                    session.reset_view()
                    collapse(page, session.system_view.folder)  # show the plots beside the scene
                    time.sleep(3.0)  # camera settles, plot markers refresh
                    close_toasts(page)
                    path = os.path.join(out_dir, f"{name}.png")
                    page.screenshot(path=path, timeout=120000)
                    written.append(path)
                    page.close()
            finally:
                browser.close()
    finally:
        app.stop()
    return written


if __name__ == "__main__":
    import argparse

    ap = argparse.ArgumentParser(prog="python -m web.screenshot")
    ap.add_argument("--out", default="docs/screenshots")
    ap.add_argument("--systems", nargs="*", default=[], help="systems files to load first")
    ap.add_argument("names", nargs="*", help="systems to capture (default: all)")
    args = ap.parse_args()
    if args.systems:
        from nmkane_core.run.plugins import load_systems

        load_systems(args.systems)
    for path in capture(args.out, args.names or None):
        print(path)
