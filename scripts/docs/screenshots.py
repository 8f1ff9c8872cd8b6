"""Every catalogue system's first view, as pictures for the docs (issue 43, item 2).

    .venv/bin/python scripts/docs/screenshots.py [--out docs/screenshots] [--width 1280 --height 800]
                                                 [--scale 0.5] [NAME ...]
    .venv/bin/python scripts/docs/screenshots.py --matrices [NAME ...]   (default: appell-hamel)

starts the web app on a free loopback port (as the browser tests do), opens one page in
headless Chromium (Debian's ``chromium``, driven by Playwright), and for each system
(default: every registered one, ``nmkane_core.system_names()``) chooses it in the page's
*Scene* menu, waits until its first run is installed and the page shows the camera the app
placed, holds the time at 0 (the first frame) and writes ``<out>/<NAME>-first-view.png``: the
page as a visitor first sees it (scene, panel), drawn at ``--width`` × ``--height`` and scaled
by ``--scale`` (640 × 400 by default), in 256 colours.  The catalogue pages show them
(``NAME-*.png``: scripts/docs/gen_catalogue.py), ``docs/web.md`` has them side by side.

With ``--matrices`` it writes ``<out>/<NAME>-matrices.png`` instead: the control panel with the
system's *Derived matrices* folder open, the others folded.

Prints each file, its size, and how much of the free part of the canvas (left of the control
panel) the mechanism's parts span — what tests/web/test_first_view_browser.py asserts.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))  # the checkout's web and nmkane_core

HIDE_TOASTS = ".mantine-Notification-root, .mantine-Notifications-root { visibility: hidden !important; }"


def _until(cond, timeout: float, what: str) -> None:
    end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > end:
            raise TimeoutError(f"{what}: not within {timeout:g} s")
        time.sleep(0.05)


def _small_png(raw: bytes, scale: float) -> bytes:
    """The screenshot scaled (Lanczos) and stored with a palette of 256 colours."""
    from PIL import Image

    img = Image.open(io.BytesIO(raw)).convert("RGB")
    if scale != 1.0:
        img = img.resize((round(img.width * scale), round(img.height * scale)), Image.Resampling.LANCZOS)
    out = io.BytesIO()
    img.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE).save(out, "PNG", optimize=True)
    return out.getvalue()


@contextlib.contextmanager
def _page(width: int, height: int, scene: str | None = None):
    """(page, session): the web app on a free loopback port, one page of it in headless Chromium
    (notifications hidden), its first run installed; everything stopped afterwards."""
    from playwright.sync_api import sync_playwright

    from web.app import launch
    from web.chromium import CHROMIUM_ARGS, chromium_path
    from web.screenshot import open_page

    exe = chromium_path()
    if exe is None:
        raise SystemExit("headless Chromium not found (apt-get install chromium)")
    app = launch(port=0, scene=scene)
    try:
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
            try:
                page = open_page(browser, app.url + "?hideViserLogo", width=width, height=height)
                page.add_style_tag(content=HIDE_TOASTS)
                session = app.wait_for_session()
                session.wait_idle(120)
                yield page, session
            finally:
                browser.close()
    finally:
        app.stop()


def first_views(out: Path, names: list[str] | None, width: int, height: int, scale: float) -> list[Path]:
    from nmkane_core import system_names
    from tests.web._pages import PARTS
    from web.screenshot import close_toasts

    out.mkdir(parents=True, exist_ok=True)
    written = []
    with _page(width, height) as (page, session):
        for name in names or list(system_names()):
            close_toasts(page)
            title = next(t for t, n in session.choices.items() if n == name)
            if session.scene_choice.value != title:
                session.scene_choice.value = title
            _until(lambda n=name: session.traj is not None and session.traj.kind == n, 120, f"{name}: a run")
            session.wait_idle(120)
            session.set_playing(False)
            session.seek(0.0)
            session.reset_view()  # the first view (a system shown before keeps the viewer's camera)
            _until(lambda: session.camera.reset_at == 0.0, 60, f"{name}: the camera placed")
            time.sleep(1.0)  # the page draws a few frames (software WebGL: about one a second)
            raw = page.screenshot(timeout=120000)
            box = page.evaluate(PARTS, session.system_view.declared.part_names())
            path = out / f"{name}-first-view.png"
            path.write_bytes(_small_png(raw, scale))
            written.append(path)
            span = max(box["hi"][0] - box["lo"][0], box["hi"][1] - box["lo"][1])
            share = span / min(box["free"], box["canvas"][1])
            print(f"{path}  {path.stat().st_size / 1024:.0f} KB  parts span {share:.0%}", flush=True)
    return written


def matrices_view(out: Path, name: str, scale: float) -> Path:
    """``<out>/<name>-matrices.png``: the control panel with the system's *Derived matrices*
    folder open (the others folded), as a class sees it."""
    from web.screenshot import close_toasts

    with _page(1280, 2400, scene=name) as (page, session):
        session.set_playing(False)
        for folder in ("Playback", session.system_view.folder, "Plots and summary", "Derived matrices"):
            page.get_by_text(folder, exact=True).first.click()
            time.sleep(0.5)
        page.wait_for_function(
            "() => Array.from(document.querySelectorAll('img')).filter(i => i.naturalWidth > 100).length"
            f" >= {len(session.matrices.images)}",
            timeout=300000,
        )
        time.sleep(1.0)
        close_toasts(page)
        bottom = page.evaluate(
            "() => Math.max(...Array.from(document.querySelectorAll('img, pre')).map(e => e.getBoundingClientRect().bottom))"
        )
        raw = page.screenshot(clip={"x": 860, "y": 0, "width": 420, "height": bottom + 24})
    path = out / f"{name}-matrices.png"
    path.write_bytes(_small_png(raw, scale))
    print(f"{path}  {path.stat().st_size / 1024:.0f} KB", flush=True)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(prog="scripts/docs/screenshots.py", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default=str(ROOT / "docs" / "screenshots"))
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=800)
    ap.add_argument("--scale", type=float, default=0.5)
    ap.add_argument("--matrices", action="store_true", help="the derived-matrices panel of each named system instead")
    ap.add_argument("names", nargs="*", help="systems (default: every registered one)")
    args = ap.parse_args()
    if args.matrices:
        for name in args.names or ["appell-hamel"]:
            matrices_view(Path(args.out), name, 1.0)
        return
    written = first_views(Path(args.out), args.names or None, args.width, args.height, args.scale)
    total = sum(p.stat().st_size for p in written)
    print(f"{len(written)} pictures, {total / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
