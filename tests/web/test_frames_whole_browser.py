"""Each frame whole (issue 43): what the page draws for one instant agrees with itself — the
pendulum's bob sits at the end of its bar in every frame drawn — in the live page and in the
exported file, at a throttled frame rate (the tests' frame cap: a frame at most every 500 ms,
tests/web/conftest.py, and the page's processor slowed 4× through the DevTools protocol).

What is measured: just before three.js draws a frame (``scene.onBeforeRender``, after the
poses of that frame are applied and the world matrices updated), the bob's centre (a node
moved by its ``position``) and the bar's free end (the last point of a line-segments node,
moved by new ``points``), both in world coordinates; every sampled frame must have them
together, and the bob must move from frame to frame (a still scene proves nothing).  Before
web/viser_compat.py's WHOLE_FRAMES, every frame was off (by up to the bar's length: viser's
client drew the poses of a batch a frame before its props)."""

import itertools

import pytest

from tests._helpers import require_browser
from tests.web._pages import until

require_browser()

import nmkane_core
from web import export
from web.app import launch
from web.chromium import POLL_MS
from web.screenshot import close_toasts, open_page

pytestmark = pytest.mark.browser

SYSTEM = "iftomm-a01"  # a bob on a massless bar from a fixed pivot: the bar a line, the bob a ball
BOB, BAR = f"/sys/{SYSTEM}/world/P1", f"/sys/{SYSTEM}/world/bar"
FRAMES = 24  # frames sampled (about 12 s at the tests' frame cap)
CPU_SLOWDOWN = 4  # the page's main thread slowed this much while sampling
TOLERANCE_M = 1e-4  # the bar is 1 m; float32 coordinates agree to ~1e-7 m

#: ``page.evaluate(SAMPLE, [bob, bar, n, seconds])``: the next ``n`` frames drawn, each as
#: {bob, end} (world coordinates, three.js axes), read just before three.js draws the frame;
#: rejected (naming how many were drawn) after ``seconds``
SAMPLE = """([bob, bar, n, seconds]) => new Promise((resolve, reject) => {
  const m = window.__viserMutable, scene = m.scene, before = scene.onBeforeRender;
  const V = scene.position.constructor;
  const out = [];
  const done = (f) => { clearTimeout(timer); scene.onBeforeRender = before; f(); };
  const late = () => done(() => reject(new Error(out.length + ' of ' + n + ' frames drawn')));
  const timer = setTimeout(late, seconds * 1000);
  scene.onBeforeRender = function () {
    const ball = m.nodeRefFromName[bob], lines = m.nodeRefFromName[bar];
    let line = null;
    if (lines) lines.traverse((o) => { if (!line && o.geometry && o.geometry.attributes.instanceEnd) line = o; });
    if (!ball || !line) return;
    const e = line.geometry.attributes.instanceEnd, k = e.count - 1;
    const end = new V(e.getX(k), e.getY(k), e.getZ(k)).applyMatrix4(line.matrixWorld);
    out.push({bob: new V().setFromMatrixPosition(ball.matrixWorld).toArray(), end: end.toArray()});
    if (out.length >= n) done(() => resolve(out));
  };
})"""


def _gap(frame: dict) -> float:
    return sum((a - b) ** 2 for a, b in zip(frame["bob"], frame["end"], strict=True)) ** 0.5


def _sample_throttled(page) -> list[dict]:
    """FRAMES frames drawn with the page's processor slowed (the frame cap stays)."""
    cdp = page.context.new_cdp_session(page)
    cdp.send("Emulation.setCPUThrottlingRate", {"rate": CPU_SLOWDOWN})
    try:
        return page.evaluate(SAMPLE, [BOB, BAR, FRAMES, 240])
    finally:
        cdp.send("Emulation.setCPUThrottlingRate", {"rate": 1})
        cdp.detach()


def _check_whole(frames: list[dict], server: str = "") -> None:
    """``server``: what the app says of its animation, for a failure's message."""
    assert len(frames) == FRAMES
    moved = sum(a["bob"] != b["bob"] for a, b in itertools.pairwise(frames))
    assert moved >= FRAMES // 2, f"the bob moved in {moved} of {FRAMES - 1} frames: the motion was not playing{server}"
    torn = [f"frame {i}: bob {f['bob']}, bar's end {f['end']} ({_gap(f):.3f} m apart)" for i, f in enumerate(frames)]
    torn = [t for t, f in zip(torn, frames, strict=True) if _gap(f) > TOLERANCE_M]
    assert not torn, f"{len(torn)} of {FRAMES} frames drawn torn:\n" + "\n".join(torn)


@pytest.fixture(scope="module")
def app():
    handle = launch(port=0, scene=SYSTEM)
    yield handle
    handle.stop()


def _nodes_drawn(page) -> None:
    page.wait_for_function(
        "([bob, bar]) => { const m = window.__viserMutable; return !!(m && m.scene && m.nodeRefFromName[bob]"
        " && m.nodeRefFromName[bar]); }",
        arg=[BOB, BAR],
        timeout=120000,
        polling=POLL_MS,
    )


def test_each_frame_is_drawn_whole_in_the_live_page(app, browser):
    page = open_page(browser, app.url + "?hideViserLogo", width=1000, height=700)
    session = app.wait_for_session()
    assert session.wait_idle(120) and session.traj.kind == SYSTEM
    until(lambda: session.playing, 10, "the page plays")
    page.wait_for_function("() => window.__nmkaneWholeFrames === true", timeout=60000, polling=POLL_MS)
    _nodes_drawn(page)
    skipped_before = app.skipped
    sampled = _sample_throttled(page)
    server = (
        f" (server: playing {session.playing}, t = {session.t_now:.3f} s, {app.fps():.1f} frames/s, "
        f"{app.skipped - skipped_before} session frames skipped for a backlog)"
    )
    _check_whole(sampled, server)
    page.close()


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    run = nmkane_core.simulate({"system": SYSTEM, "t_final": 4.0}, progress=False)
    return export.write(run, tmp_path_factory.mktemp("frames") / "pendulum.html")


def test_each_frame_is_drawn_whole_in_the_export(browser, exported):
    context = browser.new_context(viewport={"width": 1000, "height": 700})
    page = context.new_page()
    page.goto(exported.as_uri())
    _nodes_drawn(page)
    close_toasts(page)
    page.wait_for_function("() => window.__nmkaneWholeFrames === true", timeout=60000, polling=POLL_MS)
    _check_whole(_sample_throttled(page))
    context.close()
