"""The read-only side of the control panel: plots, summary table, status text, and the
derived-matrices panel.

Plot handles are keyed ``(view kind, plot key)``; a trajectory's curves are sent once
(:meth:`PlotPanel.write`), then only the current-time marker moves (:meth:`PlotPanel.mark`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
from viser import uplot

from . import matrices as mx
from . import plots as pl


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.2e}"


class PlotPanel:
    """The plots of every view (only the chosen view's are visible) and the summary table."""

    def __init__(self, gui, views: dict):
        self.views = views
        self.summary = gui.add_markdown("")
        x_scale = {"x": uplot.Scale(time=False, auto=False, range=(0.0, 20.0))}
        self.handles = {}
        for i, view in enumerate(views.values()):
            for key, title in view.plots:
                self.handles[(view.kind, key)] = self._add_plot(gui, title, x_scale, visible=i == 0)

    def add_view(self, gui, view, order: float | None = None) -> None:
        """Plots of a view added after the page was built (a system chosen later), hidden."""
        self.views[view.kind] = view
        x_scale = {"x": uplot.Scale(time=False, auto=False, range=(0.0, 20.0))}
        for i, (key, title) in enumerate(view.plots):
            self.handles[(view.kind, key)] = self._add_plot(
                gui, title, x_scale, visible=False, order=None if order is None else order + 1e-3 * i
            )

    @staticmethod
    def _add_plot(gui, title: str, x_scale: dict, visible: bool = True, order: float | None = None):
        z = np.zeros(2)
        return gui.add_uplot(
            order=order,
            data=(z, z),
            series=(uplot.Series(label="t [s]"), uplot.Series(label="—", stroke=pl.COLORS[0], width=2)),
            title=title,
            scales=x_scale,
            axes=pl.marker_axes(0.0),
            aspect=1.9,
            visible=visible,
        )

    def show_kind(self, kind: str) -> None:
        for (k, _), h in self.handles.items():
            h.visible = k == kind

    def write(self, traj, t_now: float) -> None:
        """A new trajectory's curves (series styles from its view), x range and marker."""
        view = self.views[traj.kind]
        end = max(traj.t_end, 1e-3)
        for key, curves in traj.plots.items():
            h = self.handles[(traj.kind, key)]
            series = (
                uplot.Series(label="t [s]"),
                *(
                    uplot.Series(label=lab, width=2, **view.series_style(key, i, traj))
                    for i, lab in enumerate(curves.labels)
                ),
            )
            scales = {"x": uplot.Scale(time=False, auto=False, range=(0.0, end))}
            if tuple(h.series) != series:
                h.series = series
            if h.scales != scales:
                h.scales = scales
            h.data = curves.data()
            h.axes = pl.marker_axes(t_now)
        self.summary.content = summary_table(traj)

    def mark(self, traj, t_now: float) -> None:
        for key in traj.plots:
            self.handles[(traj.kind, key)].axes = pl.marker_axes(t_now)


def summary_table(traj) -> str:
    labels = list(traj.runs)
    rows = ["| | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
    rows.append("| status | " + " | ".join(r.summary["status"] for r in traj.runs.values()) + " |")
    rows.append(
        "| max \\|ΔE\\| [J] | " + " | ".join(_fmt(r.summary["max_abs_energy_drift"]) for r in traj.runs.values()) + " |"
    )
    names = []
    for r in traj.runs.values():
        names += [n for n in r.summary["max_abs_violation"] if n not in names]
    for n in names:
        rows.append(
            f"| max \\|φ\\| {n} | "
            + " | ".join(_fmt(r.summary["max_abs_violation"].get(n)) for r in traj.runs.values())
            + " |"
        )
    rows.append("| t_end [s] | " + " | ".join(f"{float(r.t[-1]):g}" for r in traj.runs.values()) + " |")
    return "\n".join(rows)


def status_text(traj, installs: int) -> str:
    lines: list[str] = []
    groups: dict[tuple[str, str], list[str]] = {}
    for label, run in traj.runs.items():  # runs with the same outcome share a line
        groups.setdefault((run.summary["status"], run.summary["message"]), []).append(label)
    for (status, message), labels in groups.items():
        flag = {"ok": "", "event": "⏹ "}.get(status, "⚠ ")  # an event ends a run as declared: no warning
        lines.append(f"{flag}**{', '.join(labels)}: {status}** — {message}")
    for label, run in traj.runs.items():
        s = run.summary
        for sw in s.get("switches", []):
            lines.append(f"↪ {label}: t = {sw['t']:.3f} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.1e})")
        for w in s.get("warnings", []):
            lines.append(f"⚠ {label}: {w}")
    st = traj.request["settings"]
    lines.append(
        f"Δt = {st['dt']:g} s · update {installs} (#{traj.seq}) in "
        f"{(time.perf_counter() - traj.t_request) * 1e3:.0f} ms "
        f"(simulation {traj.compute_s * 1e3:.0f} ms)"
    )
    return "  \n".join(lines)


class MatricesPanel:
    """The derived matrices of the shown model, drawn in the background (:mod:`web.matrices`).

    ``lock`` is the session's lock and ``alive()`` says whether its browser is still there:
    a panel finished after the browser left is not sent."""

    def __init__(self, gui, lock, alive: Callable[[], bool]):
        self.lock, self.alive = lock, alive
        self.key: tuple[str, str] | None = None
        self.intro = gui.add_markdown("(computed in the background …)")
        blank = np.full((2, 2, 4), 255, np.uint8)
        self.images = {
            name: gui.add_image(blank, label=None, format="png", visible=False) for name in (*mx.MATRICES, "where")
        }
        self.latex = gui.add_markdown("", visible=False)

    def show(self, system: str, variant: str) -> None:
        key = (system, variant)
        if key == self.key:
            return
        self.key = key
        panel = mx.cached(system, variant)
        if panel is not None:
            self._show(panel)
        else:
            self.intro.content = f"(deriving the matrices of {system}, {variant} …)"
            threading.Thread(target=self._fill, args=key, daemon=True, name="nmkane-matrices").start()

    def _fill(self, system: str, variant: str) -> None:
        panel: mx.Panel | Exception
        try:
            panel = mx.panel(system, variant)
        except Exception as e:  # a teaching aid must never take the session down
            panel = e
        with self.lock:  # not while the session closes
            if self.key != (system, variant) or not self.alive():
                return
            if isinstance(panel, Exception):
                self.intro.content = f"(matrices unavailable: {panel})"
            else:
                self._show(panel)

    def _show(self, panel: mx.Panel) -> None:
        if not self.alive():
            return
        self.intro.content = panel.intro + (
            "  \nn₁, … (last image) name the sums in denominators." if panel.where is not None else ""
        )
        imgs = {name: panel.where if name == "where" else panel.images.get(name) for name in self.images}
        width = max(i.shape[1] for i in imgs.values() if i is not None)
        for name, h in self.images.items():
            img = imgs[name]
            if img is None:
                h.visible = False
            else:  # one width for all: the panel scales them alike
                h.image = np.pad(img, ((0, 0), (0, width - img.shape[1]), (0, 0)), constant_values=255)
                h.visible = True
        self.latex.content = "LaTeX:\n\n```latex\n" + "\n\n".join(panel.latex.values()) + "\n```"
        self.latex.visible = True
