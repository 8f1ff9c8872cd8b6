"""Every registered system's first view in headless Chromium, the first opened by its link
(``/?system=NAME``), the others chosen in the page's *Scene* menu: the camera is where the
page put it, the view is not blank, differs from the other systems', and its moving bodies
cover a reasonable share of the part of the canvas the panel leaves free (the pixels that
change when the bodies are hidden).

``NMKANE_SHOTS=/a/folder`` keeps the screenshots to look at."""

import os
from pathlib import Path

import numpy as np
import pytest

from tests._helpers import require_browser
from tests.web._pages import DRAWN, png, until
from web.screenshot import close_toasts, open_page

require_browser()

from nmkane_core.run.plugins import load_systems
from nmkane_core.run.registry import system_names
from web.app import launch
from web.camera import PANEL_PX

pytestmark = pytest.mark.browser
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "isokinetic_bowl.py"
SHOTS = os.environ.get("NMKANE_SHOTS")  # a folder: keep the screenshots to look at
W, H = 1280, 800
MIN_SHARE = 0.001  # of the free canvas covered by the moving bodies (a 20-pixel ball: 0.05 %)
MIN_SPAN = 0.05  # the moving bodies' extent on the screen, of the free canvas' width or height


def _drawn(page) -> None:
    """Two animation frames, drawn now (not at the tests' frame cap's pace): what the scene
    holds now is on the canvas."""
    page.evaluate(DRAWN)


def _camera(page) -> np.ndarray:
    """The browser's camera position in the scene's coordinates (three.js has y up: x3 = −y, y3 = z, z3 = −x)."""
    x3, y3, z3 = page.evaluate("() => window.__viserMutable.camera.position.toArray()")
    return np.array([-z3, -x3, y3], float)


def _hidden(page, paths: list[str]) -> bool:
    js = "(ps) => ps.every((p) => { const n = window.__viserMutable.nodeRefFromName[p]; return !n || !n.visible; })"
    return bool(page.evaluate(js, paths))


def _first_view(page, session, name: str) -> dict:
    """The view of system ``name`` as the page first shows it (its run installed), then again
    with its bodies hidden."""
    shown = lambda: session.kind == name and session.traj is not None and session.traj.kind == name  # noqa: E731
    until(shown, 120, f"{name}: a run")
    assert session.wait_idle(120) and session.traj.kind == name
    close_toasts(page)
    session.set_playing(False)
    session.seek(0.3 * session.traj.t_end)
    session.reset_view()
    placed = lambda: session.camera.placed[1]  # noqa: E731  (a late install may frame it again)
    until(
        lambda: np.allclose(_camera(page), placed(), atol=1e-3 * (1 + np.linalg.norm(placed()))),
        60,
        f"{name}: the camera placed",
    )
    _drawn(page)
    raw = page.screenshot(timeout=180000)
    shot = png(raw)
    d = session.system_view.declared
    nodes = [*d.frames.values(), *(m.node for m in d.moving)]
    paths = [n.name for n in nodes]
    with session.lock:
        for n in nodes:
            n.visible = False
    session.target.flush()
    until(lambda: _hidden(page, paths), 30, f"{name}: the bodies hidden")
    _drawn(page)
    bare = png(page.screenshot(timeout=180000))
    if SHOTS:
        Path(SHOTS).mkdir(parents=True, exist_ok=True)
        Path(SHOTS, f"{name}.png").write_bytes(raw)
    return {"shot": shot, "bare": bare, "follows": bool(session.follow.value), "text": page.inner_text("body")}


def _views(browser, app, names: list[str]) -> dict[str, dict]:
    """Each system's first view: the first opened by its link (``/?system=NAME``), the others
    chosen in the same page's *Scene* menu, as a teacher goes through them (a page takes ~7 s
    to open in software-drawn Chromium: one page, not one per system)."""
    page = open_page(browser, f"{app.url}?hideViserLogo&system={names[0]}", width=W, height=H)
    try:
        until(lambda: len(app.sessions) == 1, 60, "the page's session")
        session = next(iter(app.sessions.values()))
        views = {}
        for name in names:
            if session.kind != name:
                session.scene_choice.value = next(t for t, n in session.choices.items() if n == name)
            views[name] = _first_view(page, session, name)
        return views
    finally:
        page.close()


def test_every_systems_first_view_frames_its_moving_bodies(browser):
    assert load_systems([str(EXAMPLE)]) == []
    names = list(system_names())
    app = launch(port=0)
    try:
        views = _views(browser, app, names)
    finally:
        app.stop()
    free = slice(0, int(W - PANEL_PX))
    shares, spans, under = {}, {}, {}
    for name, v in views.items():
        img = v["shot"][:, free]
        assert img.mean(axis=2).std() > 0.03, f"{name}: the 3D view is blank"
        assert "Energy drift" in v["text"] and "Fit view" in v["text"]
        changed = np.abs(v["shot"] - v["bare"]).max(axis=2) > 0.08
        v["drawn"] = changed[:, free]
        shares[name] = float(changed[:, free].mean())
        under[name] = float(changed[:, int(W - PANEL_PX + 20) :].mean())
        rows, cols = np.nonzero(changed[:, free])
        spans[name] = max(np.ptp(rows) / H, np.ptp(cols) / (W - PANEL_PX)) if len(rows) else 0.0
    print("moving bodies' share of the free view:", {k: f"{v:.3%}" for k, v in shares.items()})
    print("their span (largest side / the free view's):", {k: f"{v:.2f}" for k, v in spans.items()})
    for name in views:
        assert shares[name] >= MIN_SHARE, f"{name}: the moving bodies cover {shares[name]:.2%} of the free view"
        assert spans[name] >= MIN_SPAN, f"{name}: the moving bodies span {spans[name]:.0%} of the free view"
        assert under[name] < 0.2 * shares[name], f"{name}: the bodies are drawn under the panel"
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            # compared where either draws its bodies: a thin linkage and a pendulum on a white
            # background differ in few pixels of the whole view, but in most of their own
            either = views[a]["drawn"] | views[b]["drawn"]
            diff = np.abs(views[a]["shot"][:, free] - views[b]["shot"][:, free]).max(axis=2)[either].mean()
            assert diff > 0.05, f"{a} and {b} look the same where they draw their bodies ({diff:.4f})"
