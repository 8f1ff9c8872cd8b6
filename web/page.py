"""The browser page's own side of a session: its address bar, its clipboard, its renderer,
its frames.

viser 1.1 gives the server no view of the page's address (its websocket URL drops the
query) and no public way to run script in the page, but its client runs the source of a
``RunJavascriptMessage`` (the message viser itself uses to load plotly) and exposes
``window.__viserMutable.sendMessage`` (both reached through :mod:`web.viser_compat`).
:class:`PageBridge` uses both: a small script asks the page for ``location.search`` or
copies ``location.href`` to the clipboard and answers through a hidden text box of the
session (what typing in a box sends), and another writes the address with
``history.replaceState`` (no reload, no history entry).  Everything sent to the page is
JSON-encoded data in a fixed script, so nothing typed by a person or read from a link
becomes code.  :meth:`PageBridge.whole_frames` makes the page draw every frame whole
(:data:`web.viser_compat.WHOLE_FRAMES`).

Without a browser (a test's shared server, or a viser whose internals differ) the bridge
does nothing and says so: ``active`` is False.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from . import viser_compat as compat

_ASK = "send({kind: 'address', search: window.location.search});"

# the WebGL renderer that draws the scene, once its canvas exists (asked again every half second,
# at most a minute: the canvas is made after the page connects)
_RENDERER = """
let tries = 0;
const ask = () => {
  const c = document.querySelector('canvas[data-engine]');
  if (!c) { if (++tries < 120) setTimeout(ask, 500); return; }
  let name = '';
  try {
    const gl = c.getContext('webgl2') || c.getContext('webgl');
    const ext = gl && gl.getExtension('WEBGL_debug_renderer_info');
    name = gl ? String(gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER)) : '';
  } catch (e) {}
  send({kind: 'renderer', name: name});
};
ask();
"""

#: words in a WebGL renderer's name that say it draws on the processor, without a graphics card
SOFTWARE_RENDERERS = ("swiftshader", "llvmpipe", "softpipe", "software", "basic render")


def is_software(renderer: str) -> bool:
    """Whether the WebGL renderer ``renderer`` (its name as the page reports it) is software."""
    return any(word in renderer.lower() for word in SOFTWARE_RENDERERS)


_WRITE = """
const cur = new URLSearchParams(window.location.search);
const keep = [];
for (const [k, v] of cur) if (!OURS.includes(k) && !PREFIXES.some((p) => k.startsWith(p))) keep.push([k, v]);
const enc = (s) => encodeURIComponent(s).replace(/%2F/g, '/').replace(/%3A/g, ':');
const parts = keep.concat(PAIRS).map(([k, v]) => (v === '' ? enc(k) : enc(k) + '=' + enc(v)));
const here = window.location;
const url = here.pathname + (parts.length ? '?' + parts.join('&') : '') + here.hash;
if (url !== here.pathname + here.search + here.hash) history.replaceState(null, '', url);
send({kind: 'written', search: window.location.search});
"""

_COPY = """
const href = window.location.href;
const done = (ok) => send({kind: 'copied', href: href, ok: ok});
const fallback = () => {
  try {
    const t = document.createElement('textarea');
    t.value = href; t.style.position = 'fixed'; t.style.opacity = '0';
    document.body.appendChild(t); t.select();
    const ok = document.execCommand('copy'); t.remove(); done(ok);
  } catch (e) { done(false); }
};
if (navigator.clipboard && window.isSecureContext) navigator.clipboard.writeText(href).then(() => done(true), fallback);
else fallback();
"""


_PLOTS = """
if (window.__nmkPlots) return;
window.__nmkPlots = true;
let hovered = false;
const zoomed = new Set();
const tip = document.createElement('div');
tip.className = 'nmk-tip';
tip.style.cssText = 'position:fixed;pointer-events:none;z-index:10000;display:none;white-space:pre;' +
  'background:rgba(255,255,255,0.96);border:1px solid #aaa;border-radius:4px;padding:3px 6px;' +
  'font:11px/1.35 sans-serif;color:#222;box-shadow:0 1px 4px rgba(0,0,0,0.2)';
document.body.appendChild(tip);
const report = () => send({kind: 'plots', busy: hovered || zoomed.size > 0});
const plotOf = (el) => (el && el.closest ? el.closest('.uplot') : null);
document.addEventListener('mousemove', (e) => {
  const over = e.target && e.target.closest ? e.target.closest('.u-over') : null;
  const plot = plotOf(over);
  if (!plot) {
    if (hovered) { hovered = false; tip.style.display = 'none'; report(); }
    return;
  }
  if (!hovered) { hovered = true; report(); }
  requestAnimationFrame(() => {  // after uPlot has written the values under the cursor
    const rows = Array.from(plot.querySelectorAll('.u-legend .u-series'));
    const valued = (r) => { const v = r.querySelector('.u-value'); return !!(v && v.innerText.trim()); };
    const text = rows.filter((r) => !r.classList.contains('u-off') && valued(r)).map((r) => {
      const l = r.querySelector('.u-label'), v = r.querySelector('.u-value');
      return (l ? l.innerText : '') + ' = ' + (v ? v.innerText : '');
    }).join('\\n');
    tip.textContent = text;
    tip.style.display = text ? 'block' : 'none';
    const w = tip.offsetWidth, h = tip.offsetHeight;
    tip.style.left = Math.max(4, e.clientX - w - 14) + 'px';  // left of the cursor: the panel is at the right
    tip.style.top = Math.min(window.innerHeight - h - 4, e.clientY + 12) + 'px';
  });
});
let dragged = null;  // the plot a drag started on: uPlot zooms it on mouseup when a stretch was selected
document.addEventListener('mousedown', (e) => { dragged = plotOf(e.target); }, true);
document.addEventListener('mouseup', () => {
  const plot = dragged;
  dragged = null;
  if (!plot) return;
  const sel = plot.querySelector('.u-select');  // read before uPlot clears it (this runs first: capture)
  if (sel && sel.offsetWidth > 2) { zoomed.add(plot); report(); }
}, true);
setInterval(() => {  // a chart rebuilt (a new run, another system) has lost its zoom
  let gone = false;
  for (const p of zoomed) if (!p.isConnected) { zoomed.delete(p); gone = true; }
  if (gone) report();
}, 1000);
document.addEventListener('dblclick', (e) => {
  const plot = plotOf(e.target);
  if (plot && zoomed.delete(plot)) report();
});
"""


# the plots' width (px), reported when it changes (looked at every second: a window resized, the
# panel's layout changed); the first plot drawn in the panel (an expanded copy comes later)
_PLOT_WIDTH = """
if (window.__nmkPlotWidth) return;
window.__nmkPlotWidth = true;
let width = 0;
const look = () => {
  const plot = Array.from(document.querySelectorAll('.uplot')).find((p) => p.offsetWidth > 0);
  const w = plot ? plot.offsetWidth : 0;
  if (w > 0 && Math.abs(w - width) >= 1) { width = w; send({kind: 'plot width', width: w}); }
};
look();
setInterval(look, 1000);
"""


class PageBridge:
    """Scripts for one browser's page, answered through a hidden text box.

    ``on_answer(dict)`` gets each answer: ``{"kind": "address", "search": "?…"}``,
    ``{"kind": "written", "search": …}``, ``{"kind": "copied", "href": …, "ok": bool}``,
    ``{"kind": "plots", "busy": bool}``, ``{"kind": "renderer", "name": …}``,
    ``{"kind": "plot width", "width": px}``."""

    def __init__(self, gui, client, on_answer: Callable[[dict], None]):
        self.client = client
        self._on_answer = on_answer
        self.inbox = gui.add_text("page", "", visible=False)
        self.inbox.on_update(lambda _: self._received(self.inbox))
        # a box of its own for the renderer's one answer: viser's client sends only the latest
        # update of a box within its throttle window, and this answer, sent as the page's link
        # was answered, replaced that answer (the page never opened on its link)
        self.renderer_inbox = gui.add_text("page renderer", "", visible=False)
        self.renderer_inbox.on_update(lambda _: self._received(self.renderer_inbox))
        # and one for the plots' width, so that it never takes the place of a "plots" answer
        self.plot_inbox = gui.add_text("page plots", "", visible=False)
        self.plot_inbox.on_update(lambda _: self._received(self.plot_inbox))
        self.active = compat.queue(client) is not None

    def _received(self, box) -> None:
        try:
            answer = json.loads(box.value)
        except (TypeError, ValueError):
            return
        if isinstance(answer, dict):
            self._on_answer(answer)

    def run(self, body: str, inbox=None, **data: Any) -> bool:
        """Run a script in the page: ``body`` with the names of ``data`` bound to their values
        (JSON) and ``send(obj)`` answering (into ``inbox``, default the shared one); False when
        there is no page to run it in."""
        if self.client is None:
            return False
        binds = "".join(f"const {k} = {json.dumps(v)};" for k, v in data.items())
        box = inbox if inbox is not None else self.inbox
        source = "(function () {" + compat.page_send(compat.gui_uuid(box)) + binds + body + "})();"
        return compat.run_javascript(self.client, source)

    def ask_address(self) -> bool:
        return self.run(_ASK)

    def write_address(self, pairs: list[tuple[str, str]], ours: tuple[str, ...], prefixes: tuple[str, ...]) -> bool:
        """Put ``pairs`` in the address bar, keeping the page's other parameters (viser's own:
        ``websocket``, ``hideViserLogo``, …) and dropping the ones named ``ours``/``prefixes``."""
        return self.run(_WRITE, PAIRS=[list(p) for p in pairs], OURS=list(ours), PREFIXES=list(prefixes))

    def ask_renderer(self) -> bool:
        """The page's WebGL renderer, once its scene's canvas exists: ``{"kind": "renderer", "name": …}``."""
        return self.run(_RENDERER, inbox=self.renderer_inbox)

    def copy_address(self) -> bool:
        return self.run(_COPY)

    def whole_frames(self) -> bool:
        """Every frame drawn whole (:data:`web.viser_compat.WHOLE_FRAMES`): what the server
        sends for one instant is shown together; False when there is no page."""
        return self.client is not None and compat.run_javascript(self.client, compat.whole_frames_source())

    def help_plots(self) -> bool:
        """Values under the cursor at the cursor (read from uPlot's live legend), the viewer's
        pointing and zooming reported: ``{"kind": "plots", "busy": bool}``, and the plots' width:
        ``{"kind": "plot width", "width": px}`` (a phase portrait's equal scales are computed for it)."""
        return self.run(_PLOTS) and self.run(_PLOT_WIDTH, inbox=self.plot_inbox)
