"""The read-only side of the control panel: plots, summary table, status text, and the
derived-matrices panel.

Plot handles are keyed ``(view kind, plot key)``; a trajectory's curves are sent once
(:meth:`PlotPanel.write`), then only the current-time marker moves (:meth:`PlotPanel.mark`).
A phase portrait (y against another quantity than t) is a uPlot of its own per view, its
current point marked by two crossing grid lines; its axes have equal scales when the two
quantities share a unit, computed for the plot's pixel box (the page reports the plots'
width: :meth:`PlotPanel.set_width`).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from contextlib import AbstractContextManager

import numpy as np
from viser import uplot

from . import curves as cv
from . import matrices as mx
from . import plots as pl

LONG_S = 60.0  # a run longer than this shows its plotted quantity in pages …
WINDOW_S = 30.0  # … of this many seconds, following the time
#: a phase portrait's points per pixel of the plot's width, at most (uPlot thins a line with 4 or
#: more per pixel column by column, which assumes increasing x: see :func:`web.curves.phase_data`)
PHASE_POINTS_PER_PX = 3.5
PHASE_TITLE = "Plotted quantity (phase portrait)"
PLOT_HELP = (
    "Point at a plot for the values under the cursor; drag across it to zoom, double-click to zoom "
    "out. *Plot y* and *against x* take any expression of the run's quantities (t, the coordinates "
    "and speeds, E, dE, `phi_NAME` of a constraint), e.g. `u1*cos(theta)`; x other than t draws a phase "
    "portrait, whose title gives the point at the shown time."
)


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.2e}"


class PlotPanel:
    """The plots of every view (only the chosen view's are visible) and the summary table.

    The current-time marker is a grid line of the plot's axes: changing the axes rebuilds
    the chart in the page (viser's uPlot component), which would drop a zoom and the values
    shown under the cursor, so while the viewer points at a plot or has zoomed one
    (``busy``, reported by the page: :mod:`web.plotpage`) the marker waits.  A run longer
    than :data:`LONG_S` shows its plotted quantity in pages of :data:`WINDOW_S` that follow
    the time (its oscillations, not their envelope)."""

    def __init__(self, gui, views: dict):
        self.views = views
        self.gui = gui
        self.busy = False
        self.width = pl.PLOT_WIDTH_PX  # a plot's width in the page (px), as the page last reported it
        self.pages: dict[tuple[str, str], int] = {}  # (kind, key) -> the window shown
        gui.add_markdown(PLOT_HELP)
        self.summary = gui.add_markdown("")
        self.handles: dict = {}
        self.phases: dict = {}  # kind -> the uPlot of its phase portrait
        self.phase_on: dict[str, bool] = {}  # kind -> its plotted quantity is a phase portrait
        self._phase_now: dict[str, tuple[tuple[float, float], float]] = {}  # kind -> (the point its marker shows, at t)
        self._phase_layout: dict[str, tuple] = {}  # kind -> (y axis px, padding) it was sent with
        self._shown = None  # the trajectory last written
        self._y_axes: dict[tuple[str, str], int] = {}  # (kind, key) -> its y axis' width (px), for its values
        for i, view in enumerate(views.values()):
            self._add_view_plots(gui, view, visible=i == 0)

    def add_view(self, gui, view, order: float | None = None) -> None:
        """Plots of a view added after the page was built (a system chosen later), hidden."""
        self.views[view.kind] = view
        self._add_view_plots(gui, view, visible=False, order=order)

    def _add_view_plots(self, gui, view, visible: bool, order: float | None = None) -> None:
        x_scale = {"x": uplot.Scale(time=False, auto=False, range=(0.0, 20.0))}
        for i, (key, title) in enumerate(view.plots):
            at = None if order is None else order + 1e-3 * i
            self.handles[(view.kind, key)] = self._add_plot(gui, title, x_scale, visible=visible, order=at)
        z = np.zeros(2)
        self.phases[view.kind] = gui.add_uplot(
            order=order,
            data=(np.array([-1.0, 1.0]), z),
            series=(uplot.Series(label="x"), uplot.Series(label="—", stroke=pl.COLORS[0], width=2, auto=False)),
            title=PHASE_TITLE,
            scales={"x": uplot.Scale(time=False, auto=False, range=(-2.0, 2.0))},
            axes=pl.phase_axes(0.0, 0.0, "x", "y"),
            cursor=uplot.Cursor(show=False),  # values under a cursor need increasing x
            legend=uplot.Legend(live=False),
            aspect=pl.ASPECT,
            padding=pl.PADDING,
            visible=False,
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
            aspect=pl.ASPECT,
            padding=pl.PADDING,
            visible=visible,
        )

    def show_kind(self, kind: str) -> None:
        for (k, key), h in self.handles.items():
            h.visible = k == kind and not (key == "coord" and self._phase_shown(k))
        for k, h in self.phases.items():
            h.visible = k == kind and self._phase_shown(k)

    def _phase_shown(self, kind: str) -> bool:
        return self.phase_on.get(kind, False)

    def write(self, traj, t_now: float) -> None:
        """A new trajectory's curves (series styles from its view), x range and marker."""
        view = self.views[traj.kind]
        phase = traj.plots.get("phase")
        self._shown = traj
        self.phase_on[traj.kind] = phase is not None
        for key, curves in traj.plots.items():
            if key == "phase":
                continue
            h = self.handles[(traj.kind, key)]
            series = (
                uplot.Series(label=curves.x_label),
                *(
                    uplot.Series(label=lab, width=2, **view.series_style(key, i, traj))
                    for i, lab in enumerate(curves.labels)
                ),
            )
            if tuple(h.series) != series:
                h.series = series
            self.pages.pop((traj.kind, key), None)
            self._send(h, traj, key, curves, t_now, force=True)
        self.show_kind(traj.kind)
        if phase is not None:
            self._send_phase(traj.kind, phase, t_now)
        self.summary.content = summary_table(traj)

    def set_width(self, width: float) -> None:
        """The page reports how wide its plots are (px): a shown phase portrait of two lengths is
        drawn again, its equal scales computed for its new pixel box."""
        width = float(width)
        if not (math.isfinite(width) and 100.0 <= width <= 4000.0) or abs(width - self.width) < 0.5:
            return
        self.width = width
        traj = self._shown
        if traj is not None and traj.plots.get("phase") is not None:
            self._send_phase(traj.kind, traj.plots["phase"], self._phase_t(traj.kind))

    def _phase_t(self, kind: str) -> float:
        return self._phase_now.get(kind, ((0.0, 0.0), 0.0))[1]

    def phase_layout(self, phase) -> tuple[tuple[float, float], tuple[float, float], int, tuple[int, int, int, int]]:
        """A phase portrait's x and y ranges, y axis width and padding for the plot's pixel box:
        equal scales when its axes share a unit (:func:`web.plots.equal_ranges`), else each axis
        its own (:func:`web.plots.padded`); the axis and the padding wide enough for the values."""
        (x_lo, x_hi), (y_lo, y_hi) = phase.box()
        y_axis, padding = pl.Y_AXIS_PX, pl.PADDING
        xr, yr = pl.padded(x_lo, x_hi), pl.padded(y_lo, y_hi)
        for _ in range(2):  # the ranges set the values' widths, which set the box: once more settles it
            box = pl.plot_box(self.width, y_axis, padding)
            if phase.equal:
                xr, yr = pl.equal_ranges((x_lo, x_hi), (y_lo, y_hi), box)
            y_axis = pl.y_axis_px(*yr, box[1])
            padding = pl.x_padding(xr, box[0])
        return xr, yr, y_axis, padding

    def _send_phase(self, kind: str, phase, t_now: float) -> None:
        """A phase portrait's series, ranges, layout and data (then only its marker moves)."""
        h = self.phases[kind]
        xr, yr, y_axis, padding = self.phase_layout(phase)
        box = pl.plot_box(self.width, y_axis, padding)
        styles = phase.styles
        series = (
            uplot.Series(label=phase.x_label),
            *(  # auto=False: the NaN of the other runs' stretches never reach a range
                uplot.Series(label=lab, width=2, auto=False, **(styles[i] if i < len(styles) else {}))
                for i, lab in enumerate(phase.labels)
            ),
        )
        if tuple(h.series) != series:
            h.series = series
        h.scales = {
            "x": uplot.Scale(time=False, auto=False, range=xr),
            "y": uplot.Scale(auto=False, range=yr),
        }
        h.padding = padding
        h.data = cv.phase_data(phase, max(200, int(PHASE_POINTS_PER_PX * box[0])))
        self._phase_layout[kind] = (y_axis, padding)
        self._phase_now.pop(kind, None)
        self._mark_phase(kind, phase, t_now)

    def _range(self, traj, key: str, t_now: float) -> tuple[float, float, int]:
        """The x range shown (the whole run, or the page of a long run that holds t_now)."""
        end = max(traj.t_end, 1e-3)
        if key != "coord" or end <= LONG_S:
            return 0.0, end, 0
        page = int(max(t_now, 0.0) // WINDOW_S)
        return page * WINDOW_S, min((page + 1) * WINDOW_S, end), page

    def _send(self, h, traj, key: str, curves, t_now: float, force: bool = False) -> None:
        t0, t1, page = self._range(traj, key, t_now)
        if force or self.pages.get((traj.kind, key)) != page:
            self.pages[(traj.kind, key)] = page
            data = curves.window(t0, t1) if page or t1 < traj.t_end else curves.data()
            scales = {"x": uplot.Scale(time=False, auto=False, range=(t0, t1))}
            y_range = pl.constant_range(data[1:])  # a constant: a small range around it, not uPlot's 0–100
            if y_range is not None:
                scales["y"] = uplot.Scale(auto=False, range=y_range)
            if h.scales != scales:
                h.scales = scales
            h.data = data
            span = y_range
            if span is None and (found := pl.data_range(data[1:])) is not None:
                span = pl.auto_range(*found)  # about what uPlot's own y range will be
            self._y_axes[(traj.kind, key)] = pl.y_axis_px(*span) if span is not None else pl.Y_AXIS_PX
        y_axis = self._y_axes.get((traj.kind, key), pl.Y_AXIS_PX)
        h.axes = pl.marker_axes(t_now, curves.x_label, curves.y_label, y_axis)

    def mark(self, traj, t_now: float) -> None:
        """The current-time marker (and a long run's page); it waits while the viewer is busy with a plot."""
        if self.busy:
            return
        for key, curves in traj.plots.items():
            if key == "phase":
                self._mark_phase(traj.kind, curves, t_now)
                continue
            self._send(self.handles[(traj.kind, key)], traj, key, curves, t_now)

    def _mark_phase(self, kind: str, phase, t_now: float) -> None:
        """The portrait's current point: two grid lines crossing there, and its values in the
        title (a portrait has no values under a cursor: x need not increase), sent when it moved."""
        x, y = phase.at(t_now)
        if self._phase_now.get(kind, (None, None))[0] == (x, y):
            return
        self._phase_now[kind] = ((x, y), t_now)
        y_axis = self._phase_layout.get(kind, (pl.Y_AXIS_PX, pl.PADDING))[0]
        chart = self.phases[kind]
        chart.axes = pl.phase_axes(x, y, phase.x_label, phase.y_label, y_axis)
        chart.title = phase_title(phase.x_label, phase.y_label, x, y, t_now)


def phase_title(x_label: str, y_label: str, x: float, y: float, t: float) -> str:
    """A phase portrait's title with its point at the shown time."""
    return f"Phase portrait at t = {t:.3g} s: {x_label} = {x:.4g}, {y_label} = {y:.4g}"


def summary_rows(traj) -> list[list[str]]:
    """The summary of a trajectory's runs as rows of cells: a header (the run labels), then
    status, max |ΔE|, max |φ| per constraint and the final time (the panel's table, the
    exported page's)."""
    runs = list(traj.runs.values())
    rows = [["", *traj.runs], ["status", *(r.summary["status"] for r in runs)]]
    rows.append(["max |ΔE| [J]", *(_fmt(r.summary["max_abs_energy_drift"]) for r in runs)])
    names: list[str] = []
    for r in runs:
        names += [n for n in r.summary["max_abs_violation"] if n not in names]
    for n in names:
        rows.append([f"max |φ| {n}", *(_fmt(r.summary["max_abs_violation"].get(n)) for r in runs)])
    rows.append(["t_end [s]", *(f"{float(r.t[-1]):g}" for r in runs)])
    return rows


def summary_table(traj) -> str:
    """:func:`summary_rows` as a markdown table."""
    rows = [[c.replace("|", "\\|") for c in row] for row in summary_rows(traj)]
    lines = ["| | " + " | ".join(rows[0][1:]) + " |", "|---|" + "---|" * (len(rows[0]) - 1)]
    return "\n".join(lines + ["| " + " | ".join(row) + " |" for row in rows[1:]])


def _partition_lines(traj) -> list[str]:
    """Which speeds the shown runs took independent (and the coordinates solved from ψ = 0), and
    whether the model declared it or the library picked it; runs that share one share a line."""
    groups: dict[tuple, list[str]] = {}
    for label, run in traj.runs.items():
        part = run.summary.get("partition")
        if part and run.violation:  # a constrained model
            key = (tuple(part["u_independent"]), tuple(part["q_dependent"]), part["chosen"])
            groups.setdefault(key, []).append(label)
    lines = []
    for (u_ind, q_dep, chosen), labels in groups.items():
        solved = f" · q solved from ψ = 0: {', '.join(q_dep)}" if q_dep else ""
        how = "declared" if chosen == "declared" else "picked by pivoting"
        lines.append(f"{', '.join(labels)}: u_I = {', '.join(u_ind)}{solved} ({how})")
    return lines


def _error_lines(traj) -> list[str]:
    """The estimated global error of the runs that asked for it (``error_estimate``): the largest
    over the states, and which state."""
    lines = []
    for label, run in traj.runs.items():
        est = run.summary.get("error_estimate")
        if not est:
            continue
        if not est.get("max_abs"):
            lines.append(f"± {label}: no error estimate — {est.get('message', '')}")
            continue
        name, value = max(est["max_abs"].items(), key=lambda kv: kv[1])
        lines.append(f"± {label}: estimated global error ≤ {value:.1e} ({name}; {est['method']})")
    return lines


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
    lines += _partition_lines(traj)
    lines += _error_lines(traj)
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
    a panel finished after the browser left is not sent; ``racing_a_leave()`` is the scope of the
    writes of one that finishes as it leaves (web.session.racing_a_leave: the browser can go
    between the check and the last image, and viser's warning about those dropped messages went
    to the server's log)."""

    def __init__(self, gui, lock, alive: Callable[[], bool], racing_a_leave: Callable[[], AbstractContextManager]):
        self.lock, self.alive, self.racing_a_leave = lock, alive, racing_a_leave
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
        with self.lock, self.racing_a_leave():  # not while the session closes; it may leave while this is sent
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
        # the panel's matrices in the slots in order (a model without A shows J1, J2, Q instead)
        drawn = list(panel.images.values())
        slots = [name for name in self.images if name != "where"]
        imgs = {name: drawn[i] if i < len(drawn) else None for i, name in enumerate(slots)}
        imgs["where"] = panel.where
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
