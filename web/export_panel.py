"""The exported page's side panel (:mod:`web.export`): the run's settings, its summary and
its plots — energy drift, log₁₀ |violation| per constraint, the declared forces and the
first coordinate against time, the page's own curves (:meth:`GenericView.curves`) drawn by
matplotlib as inline SVG (text as text, no external reference) — with a dashed cursor at the
time the playback bar shows.

The panel sits where the live page's control panel does (right of the canvas, the camera
frames the scene left of it) and folds away (``<details>``).  Its script reads the playback
bar's time from viser's slider (``[role=slider]``, ``aria-valuenow``: seconds of playback)
and converts it to simulated time with the recording's speed.  The page also gets the
live page's whole frames (:func:`web.viser_compat.whole_frames_script`): every recorded
instant is drawn together, the rods with the bodies.
"""

from __future__ import annotations

import html
import io
import json
import re

from nmkane_core.kernel.built import built

from . import plots as pl
from . import viser_compat as compat
from .camera import PANEL_PX
from .panel import summary_rows

PLOT_W_IN, PLOT_H_IN, DPI = 3.9, 2.2, 100  # one plot: 390 × 220 px
MAX_LEGEND = 6  # series named in a plot's legend at most

CSS = """
#nmk-panel{position:fixed;top:8px;right:8px;bottom:56px;width:%(w)dpx;overflow-y:auto;z-index:20;
 background:rgba(255,255,255,.95);border:1px solid #ccc;border-radius:8px;padding:8px 10px;
 font:12px/1.35 system-ui,-apple-system,"Segoe UI",sans-serif;color:#222;box-sizing:border-box}
#nmk-panel summary{font-weight:600;font-size:14px;cursor:pointer}
#nmk-panel table{border-collapse:collapse;margin:6px 0;width:100%%}
#nmk-panel td,#nmk-panel th{border-bottom:1px solid #e4e4e4;padding:2px 4px;text-align:left}
#nmk-panel .nmk-plot{position:relative;margin-top:6px}
#nmk-panel .nmk-plot svg{width:100%%;height:auto;display:block}
#nmk-panel .nmk-cursor{position:absolute;width:0;border-left:1.5px dashed #444;pointer-events:none}
#nmk-panel .nmk-note{color:#666;margin-top:6px}
"""

SCRIPT = """
(function () {
  var speed = %(speed)s, tEnd = %(t_end)s;
  function place() {
    var bar = document.querySelector('[role=slider][aria-valuenow]');
    var t = bar ? Math.min(Math.max(parseFloat(bar.getAttribute('aria-valuenow')) * speed, 0), tEnd) : 0;
    if (!isFinite(t)) t = 0;
    document.querySelectorAll('#nmk-panel .nmk-plot').forEach(function (p) {
      var d = p.dataset, x0 = +d.x0, x1 = +d.x1, t0 = +d.t0, t1 = +d.t1;
      var f = t1 > t0 ? Math.min(Math.max((t - t0) / (t1 - t0), 0), 1) : 0;
      var c = p.querySelector('.nmk-cursor');
      c.style.left = (100 * (x0 + f * (x1 - x0))) + '%%';
      c.style.top = (100 * (+d.top)) + '%%';
      c.style.height = (100 * (+d.height)) + '%%';
    });
    var clock = document.getElementById('nmk-time');
    if (clock) clock.textContent = t.toFixed(2);
    document.getElementById('nmk-panel').dataset.t = t;
  }
  function loop() { place(); window.requestAnimationFrame(loop); }
  loop();
})();
"""


def _svg(fig) -> str:
    """A matplotlib figure as an inline ``<svg>`` element (no prolog, doctype or metadata)."""
    import matplotlib as mpl
    from matplotlib.backends.backend_svg import FigureCanvasSVG

    buf = io.StringIO()
    with mpl.rc_context({"svg.fonttype": "none", "svg.hashsalt": "nmkane"}):
        FigureCanvasSVG(fig).print_svg(buf, metadata={"Date": None, "Creator": None, "Format": None, "Type": None})
    text = buf.getvalue()
    text = text[text.index("<svg") :]
    return re.sub(r"<metadata>.*?</metadata>", "", text, flags=re.S)


def plot_html(curves: pl.Curves, title: str) -> str:
    """One plot: the SVG and its cursor, placed over the axes by the data attributes."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(PLOT_W_IN, PLOT_H_IN), dpi=DPI)
    ax = fig.add_subplot()
    for i, (y, label) in enumerate(zip(curves.ys, curves.labels, strict=True)):
        st = curves.styles[i] if i < len(curves.styles) else {"stroke": pl.COLORS[i % len(pl.COLORS)]}
        dash = st.get("dash")
        ax.plot(curves.t, y, color=st["stroke"], lw=1.2, label=label, dashes=dash if dash else (None, None))
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(curves.x_label, fontsize=8)
    ax.set_ylabel(curves.y_label, fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
    ax.set_xlim(float(curves.t[0]), float(curves.t[-1]) if curves.t[-1] > curves.t[0] else float(curves.t[0]) + 1)
    if 1 < len(curves.labels) <= MAX_LEGEND:
        ax.legend(fontsize=6, loc="best")
    fig.tight_layout(pad=0.4)
    box = ax.get_position()
    t0, t1 = ax.get_xlim()
    data = {"x0": box.x0, "x1": box.x1, "top": 1 - box.y1, "height": box.height, "t0": t0, "t1": t1}
    attrs = " ".join(f'data-{k}="{v:.6g}"' for k, v in data.items())
    key = html.escape(title, quote=True)
    return f'<div class="nmk-plot" data-plot="{key}" {attrs}>{_svg(fig)}<div class="nmk-cursor"></div></div>'


def settings_line(view, run) -> str:
    """The settings that make the run, in one line (variant, integrator, step, time, gains)."""
    st, core = run.settings, view.core
    parts = []
    if st.get(core.option):
        parts.append(f"{core.option} {st[core.option]}")
    parts += [st["integrator"], f"Δt = {st['dt']:g} s", f"t = 0 … {st['t_final']:g} s"]
    info = built(core).info(st.get(core.option) or core.default_variant)
    gains = {"gamma": ("Γ", info.nonholonomic), "gamma1": ("Γ1", info.holonomic), "gamma2": ("Γ2", info.holonomic)}
    parts += [f"{sym} = {st[k]:g}" for k, (sym, used) in gains.items() if used and isinstance(st.get(k), (int, float))]
    if st.get("projection") not in (None, "none"):
        parts.append(f"projection {st['projection']}")
    return " · ".join(parts)


def _table(rows: list[list[str]]) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c in rows[0])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in rows[1:])
    return f"<table><tr>{head}</tr>{body}</table>"


def panel_html(view, traj, shots, title: str | None = None) -> str:
    """The panel's HTML (style, content, script)."""
    main = traj.main
    curves = view.curves(traj.runs)
    plots = [plot_html(curves[k], t) for k, t in view.plots if isinstance(curves.get(k), pl.Curves)]
    messages = "".join(
        f"<div><b>{html.escape(label)}: {html.escape(r.status)}</b> — {html.escape(r.summary['message'])}</div>"
        for label, r in traj.runs.items()
    )
    legend = html.escape(view.legend(traj).replace("**", ""))
    scale = view.forces.scale_text if view.forces.visible else ""  # the scene's labels name the forces
    heading = html.escape(title or view.title)
    speed = f"{shots.speed:g}× (the bar's time is playback time)" if shots.speed != 1 else "1× (real time)"
    return (
        f"<style>{CSS % {'w': int(PANEL_PX) - 20}}</style>"
        f'<div id="nmk-panel" data-system="{html.escape(main.system, quote=True)}"><details open>'
        f"<summary>{heading} — t = <span id='nmk-time'>0.00</span> s</summary>"
        f"<div>{html.escape(settings_line(view, main))}</div>{messages}"
        f"{f'<div>{legend}</div>' if legend else ''}"
        f"{f'<div>Force {html.escape(scale)}</div>' if scale else ''}"
        f"{_table(summary_rows(traj))}{''.join(plots)}"
        f"<div class='nmk-note'>Exported by nmkane: {len(shots.times)} frames, played at {speed}. "
        "Play, pause and scrub with the bar below; drag the scene to orbit. Works offline.</div>"
        f"</details></div>"
        f"<script>{SCRIPT % {'speed': json.dumps(shots.speed), 't_end': json.dumps(float(traj.t_end))}}</script>"
    )


def inject(page: str, view, traj, shots, title: str | None = None) -> str:
    """viser's standalone page with the panel added, each frame drawn whole, and the system's
    title as the page's."""
    name = html.escape(f"{title or view.title} — nmkane")
    page = page.replace("<title>Viser</title>", f"<title>{name}</title>", 1)
    end = page.rindex("</body>")
    return page[:end] + panel_html(view, traj, shots, title) + compat.whole_frames_script() + page[end:]
