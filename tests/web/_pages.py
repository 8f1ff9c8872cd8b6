"""Helpers of the browser tests: screenshots as arrays, and waits for what the page shows (a
deadline and a condition, never a fixed time)."""

from __future__ import annotations

import io
import time

import numpy as np

#: screenshot style: the notifications (SwiftShader's "Software WebGL rendering detected", shown
#: whenever it pleases) left out of the picture
HIDE_TOASTS = ".mantine-Notification-root, .mantine-Notifications-root { visibility: hidden !important; }"

#: ``page.evaluate(DRAWN)``: two of the page's frames drawn now, whatever the pace of the tests'
#: frame cap (tests/web/conftest.py FRAME_CAP): the first draws what the scene holds, the second
#: what the first frame's updates changed
DRAWN = "async () => { await window.__nmkaneFrameNow(); await window.__nmkaneFrameNow(); }"


#: ``page.evaluate(PARTS, names)``: the screen box (CSS pixels, canvas corner at 0, 0) of the
#: named nodes' geometry projected with the page's camera, how many points were projected and
#: behind the camera, which names the page lacks, the canvas' size and the left edge of the
#: control panel (its box holding the "Copy link" button)
PARTS = """(names) => {
  const m = window.__viserMutable, cam = m.camera, canvas = m.canvas;
  const V = cam.position.constructor;
  const rect = canvas.getBoundingClientRect();
  cam.updateMatrixWorld();
  const lo = [Infinity, Infinity], hi = [-Infinity, -Infinity];
  let points = 0, behind = 0;
  const missing = [];
  const add = (p) => {
    const q = p.clone().project(cam);
    if (q.z > 1) behind++;
    const px = [(q.x + 1) / 2 * rect.width, (1 - q.y) / 2 * rect.height];
    for (let k = 0; k < 2; k++) { lo[k] = Math.min(lo[k], px[k]); hi[k] = Math.max(hi[k], px[k]); }
    points++;
  };
  for (const name of names) {
    const node = m.nodeRefFromName[name];
    if (!node) { missing.push(name); continue; }
    node.updateWorldMatrix(true, true);
    node.traverse((o) => {
      const g = o.geometry;
      if (!g || !o.visible) return;
      const a = g.attributes;
      if (a.instanceStart) {  // line segments: their end points
        for (const s of [a.instanceStart, a.instanceEnd])
          for (let i = 0; i < s.count; i++) add(new V(s.getX(i), s.getY(i), s.getZ(i)).applyMatrix4(o.matrixWorld));
      } else if (a.position) {  // a mesh: the corners of its box
        if (!g.boundingBox) g.computeBoundingBox();
        const b = g.boundingBox;
        for (const x of [b.min.x, b.max.x]) for (const y of [b.min.y, b.max.y]) for (const z of [b.min.z, b.max.z])
          add(new V(x, y, z).applyMatrix4(o.matrixWorld));
      }
    });
  }
  let el = Array.from(document.querySelectorAll('button')).find((b) => b.textContent.includes('Copy link'));
  let panel = rect.right;
  while (el && el.parentElement) {
    const r = el.getBoundingClientRect();
    if (r.height > 0.6 * window.innerHeight && r.width < 0.6 * window.innerWidth) panel = r.left;
    el = el.parentElement;
  }
  return {lo, hi, points, behind, missing, canvas: [rect.width, rect.height], free: panel - rect.left};
}"""


def png(data: bytes) -> np.ndarray:
    """A screenshot as an RGB array of floats in [0, 1]."""
    from matplotlib.image import imread

    return imread(io.BytesIO(data), format="png")[..., :3]


def settled(shoot, timeout: float = 60.0) -> np.ndarray:
    """``shoot()`` (a screenshot, PNG bytes) once two in a row are the same: the page has drawn
    what it was sent.  A page that keeps changing fails after ``timeout`` s."""
    deadline = time.monotonic() + timeout
    last = png(shoot())
    while True:
        time.sleep(0.1)  # between two looks, not a wait for something
        now = png(shoot())
        if now.shape == last.shape and np.array_equal(now, last):
            return now
        assert time.monotonic() < deadline, f"the page did not settle within {timeout:g} s"
        last = now


def element_shot(locator, timeout: float = 60.0) -> bytes:
    """A screenshot (PNG bytes) of ``locator``'s element.  The page replaces some elements
    when it redraws them (a plot given a new quantity or a new run): one replaced while its
    screenshot was being taken ("not attached to the DOM") is looked up again, within a
    deadline — the page redrawing is an event to wait for, not a failure."""
    deadline = time.monotonic() + timeout
    while True:
        try:
            return locator.screenshot(timeout=timeout * 1000)
        except Exception as e:  # playwright's Error
            if "not attached" not in str(e) or time.monotonic() > deadline:
                raise


def until(cond, timeout: float = 60.0, what: str = "condition") -> None:
    """Poll ``cond()`` until true, within a deadline."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, f"{what}: not within {timeout:g} s"
        time.sleep(0.05)


def new_session(app, open_page):
    """The page ``open_page()`` opens and its session: ``(session, page)`` (the pages closed
    before may still have their sessions for a moment)."""
    with app._lock:
        before = set(app.sessions)
    page = open_page()
    until(lambda: set(app.sessions) - before, 30, "the page's session")  # stored once its page is built
    with app._lock:
        session = app.sessions[next(iter(set(app.sessions) - before))]
    return session, page


def label_boxes(items, view) -> list[tuple[str, tuple]]:
    """(text, screen box) of each label of ``items`` [(label node, world point)] at the anchor it
    holds, seen by ``view`` (web.labels.View)."""
    from web.labels import box

    xy, _ = view.project(np.array([p for _, p in items], float))
    return [(n.text, box(xy[i], n.text, n.anchor)) for i, (n, _) in enumerate(items)]


def covering(boxes: list[tuple[str, tuple]]) -> str | None:
    """The first two labels of ``boxes`` [(text, box)] that cover each other, said; None: none do."""
    from web.labels import overlap

    for i, (ta, a) in enumerate(boxes):
        for tb, b in boxes[i + 1 :]:
            if overlap(a, b) > 0.0:
                return f"label {ta!r} covers {tb!r} ({a} and {b})"
    return None
