"""``nmkane export ... --out run.gif``: the exported page (:mod:`web.export`) filmed in
headless Chromium — the scene with the plots panel, its cursor moving — and encoded as an
animated GIF with Pillow (a viser dependency).

The page is opened from a temporary file with the network off, paused, and for each frame
the playback bar is set to the frame's time (typed into its time box, as a person would)
before a screenshot: :data:`GIF_FPS` frames per second of playback, at most
:data:`GIF_MAX_FRAMES` (about a second per frame on two cores with software WebGL).
Needs Chromium (Debian's ``chromium``) and Playwright; without them an error says so.
"""

from __future__ import annotations

import io
import math
import tempfile
from pathlib import Path

from nmkane_core.errors import NmkaneError

from .chromium import CHROMIUM_ARGS, POLL_MS, chromium_path, close_toasts
from .export import GIF, check_out, export_page, frames, trajectory
from .runs import Trajectory

GIF_FPS = 10.0  # frames per second of playback
GIF_MAX_FRAMES = 100  # frames of one GIF at most
SIZE = (960, 540)  # pixels: the scene left of the plots panel
BAR = "document.querySelector('[role=slider][aria-valuenow]')"


def _browser():
    """Playwright's sync API and the Chromium binary, or an error saying what to install."""
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        raise NmkaneError("--out FILE.gif films the page in Chromium: pip install playwright") from None
    exe = chromium_path()
    if exe is None:
        raise NmkaneError("--out FILE.gif films the page in headless Chromium: apt-get install chromium")
    return sync_playwright, exe


def film(page_file: Path, times: list[float], size: tuple[int, int] = SIZE) -> list[bytes]:
    """Screenshots (PNG) of the exported page at each playback time (seconds of the bar),
    taken in a thread of their own: Playwright's sync API refuses a thread whose asyncio loop
    runs (Jupyter's, or a caller's own Playwright session)."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(1, thread_name_prefix="nmkane-gif") as pool:
        return pool.submit(_film, page_file, times, size).result()


def _film(page_file: Path, times: list[float], size: tuple[int, int]) -> list[bytes]:
    sync_playwright, exe = _browser()
    shots = []
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
        try:
            context = browser.new_context(viewport={"width": size[0], "height": size[1]})
            context.set_offline(True)
            page = context.new_page()
            page.goto(page_file.as_uri())
            page.wait_for_function(f"() => !!{BAR}", timeout=120000, polling=POLL_MS)
            close_toasts(page)
            bar = page.locator(".mantine-Slider-root")
            # pause: the click event itself, not a pointer's (which waits for the button to hold still
            # over two drawn frames, each seconds long in software WebGL on a busy machine)
            bar.locator("xpath=ancestor::div[.//button][1]").locator("button").first.dispatch_event("click")
            box = page.locator("input.mantine-NumberInput-input").first
            end = float(page.evaluate(f"{BAR}.getAttribute('aria-valuemax')"))  # past it the bar starts again
            for t in times:
                t = math.floor(min(t, end) * 1000) / 1000
                box.fill(f"{t:.3f}")
                box.press("Enter")
                page.wait_for_function(
                    f"() => Math.abs(parseFloat({BAR}.getAttribute('aria-valuenow')) - {t:.3f}) < 1e-6",
                    timeout=30000,
                    polling=POLL_MS,
                )
                page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
                close_toasts(page)
                shots.append(page.screenshot())
        finally:
            browser.close()
    return shots


def encode(shots: list[bytes], step_s: float, path: Path) -> None:
    """PNG screenshots as one looping GIF, ``step_s`` seconds each (an adaptive palette per frame)."""
    from PIL import Image

    images = [
        Image.open(io.BytesIO(s)).convert("RGB").quantize(colors=255, method=Image.Quantize.FASTOCTREE) for s in shots
    ]
    images[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=max(20, round(1000 * step_s)),
        loop=0,
        optimize=True,
        disposal=1,
    )


def write_gif(runs, path: str | Path) -> Path:
    """The run as an animated GIF of its exported page at ``path`` (``.gif``; written whole or
    not at all)."""
    out = check_out(path, (GIF,))
    _browser()  # no Chromium or Playwright: say so before the work
    traj = runs if isinstance(runs, Trajectory) else trajectory(runs)
    text, page_frames = export_page(traj)
    # the GIF's own frames over the same playback: GIF_FPS a second, at most GIF_MAX_FRAMES
    shots_at = frames(traj.t_end, page_frames.speed, fps=GIF_FPS, max_frames=GIF_MAX_FRAMES)
    with tempfile.TemporaryDirectory(prefix="nmkane-gif-") as tmp:
        page_file = Path(tmp) / "page.html"
        page_file.write_text(text, encoding="utf-8")
        shots = film(page_file, [float(t) / shots_at.speed for t in shots_at.times])
    partial = out.with_name(out.name + ".part")
    encode(shots, shots_at.step_s, partial)
    partial.replace(out)
    return out
