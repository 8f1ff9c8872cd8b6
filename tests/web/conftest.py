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


#: the pages' animation frames at most every 500 ms, drawn without multisampling: headless
#: Chromium draws the 3D view in software (SwiftShader) as fast as it can, and its GPU process
#: then takes both cores (133–173 % CPU measured); the app serving the page, the page's scripts and
#: the other test worker wait for it.  Capped at 200 ms, an open page still cost 0.83 of a core in
#: the GPU process (166 ms a frame at 1400×900), most of the browser tests' CPU and a fifth of the
#: whole suite's; at 500 ms and without multisampling, 0.34 (measured with the app's default page).
#: The tests wait for what a page shows, never for a number of frames; Playwright's own waits run
#: in a world of their own and keep their pace.  A test that needs the canvas to show what the
#: scene holds now (a screenshot compared pixel by pixel) calls ``window.__nmkaneFrameNow()``
#: (``tests/web/_pages.py`` DRAWN): the frames the cap holds back are drawn at the next frame,
#: and its promise resolves after them — two frames at the cap's pace took 2–6 s of each
#: system's view in the catalogue's browser test.
FRAME_CAP = """(() => {
  const raf = window.requestAnimationFrame.bind(window);
  const cancel = window.cancelAnimationFrame.bind(window);
  const held = new Map();  // timer -> callback: frames asked for, held back by the cap
  window.requestAnimationFrame = (callback) => {
    const timer = setTimeout(() => { held.delete(timer); raf(callback); }, 500);
    held.set(timer, callback);
    return timer;
  };
  window.cancelAnimationFrame = (id) => { if (held.delete(id)) clearTimeout(id); else cancel(id); };
  window.__nmkaneFrameNow = () => new Promise((resolve) => {
    for (const [timer, callback] of held) { clearTimeout(timer); raf(callback); }
    held.clear();
    raf(() => resolve());
  });
  const context = HTMLCanvasElement.prototype.getContext;
  HTMLCanvasElement.prototype.getContext = function (type, attributes) {
    if (type === "webgl2" || type === "webgl") attributes = Object.assign({}, attributes, {antialias: false});
    return context.call(this, type, attributes);
  };
})();"""


class _FrameCapped:
    """The shared Chromium, every page and context it opens with :data:`FRAME_CAP`."""

    def __init__(self, browser):
        self._browser = browser

    def new_page(self, **options):
        page = self._browser.new_page(**options)
        page.add_init_script(FRAME_CAP)
        return page

    def new_context(self, **options):
        context = self._browser.new_context(**options)
        context.add_init_script(FRAME_CAP)
        return context

    def __getattr__(self, name):
        return getattr(self._browser, name)


@pytest.fixture
def browser(_chromium):
    """The shared Chromium (frames capped: :data:`FRAME_CAP`); the pages a test leaves open are
    closed after it (each page has a browser context of its own: nothing carries over from one
    test to the next)."""
    yield _FrameCapped(_chromium)
    for context in list(_chromium.contexts):
        context.close()


def _viser_server():
    import viser

    srv = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)  # a free port
    yield srv
    srv.stop()


#: a viser server of its own for each test (the app tests' ``MechanismApp(server, sync=True)``)
server = pytest.fixture(name="server")(_viser_server)
#: one viser server for a module's tests
module_server = pytest.fixture(scope="module", name="module_server")(_viser_server)
