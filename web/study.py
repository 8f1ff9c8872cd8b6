"""The "Γ study" panel: a map of how the Baumgarte gain and the step size trade off, for the
system and settings on the page.

One press of *Compute the map* runs a small grid — :data:`N_GAIN` values of the chosen gain
(Γ, or Γ1 / Γ2 for holonomic constraints; whichever the page's system has) over the gain
slider's range up to 0, × :data:`N_DT` step sizes around the page's Δt — through the
sweep machinery of :mod:`nmkane_core.sweep` (:func:`~nmkane_core.sweep.run_sweep`, one run
after another in a background thread), over a short horizon, with the page's other settings.
A progress bar moves batch by batch; the animation keeps playing (the thread takes the
session lock only to update the panel).  The map (matplotlib → an image) colours each cell by
log10 max|violation| or log10 max|ΔE| (a chooser; changing it redraws without running
again); runs that did not end ``ok`` are grey and say why.

viser's images do not report where they were clicked (1.1: ``GuiImageHandle`` has no click
event), so a cell is chosen in the *Cell* dropdown (grid order, each entry with its value)
and marked on the map; *Load cell* puts its gain and Δt into the page's sliders (one
re-simulation), *Load best cell* the one with the smallest value.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from nmkane_core.sweep.executors import SerialExecutor
from nmkane_core.sweep.plot import metric_values
from nmkane_core.sweep.runner import run_sweep
from nmkane_core.sweep.spec import Axis, SweepSpec

from .controls import DT_RANGE, dt_of, settings_from

__all__ = ["METRICS", "StudyGrid", "StudyPanel", "study_axes", "study_grid"]

N_GAIN, N_DT = 6, 5  # 30 runs
HORIZON_S = 2.0  # default horizon of each run (the page's final time if shorter)
ROWS_PER_RUN = 200  # output rows kept per run (the summary's maxima use every step)
TIME_LIMIT_S = 10.0  # a run that takes longer ends 'timeout' (a grey cell)
GAIN_FIELDS = {"gamma": "Γ", "gamma1": "Γ1", "gamma2": "Γ2"}
METRICS = {  # the chooser's entry -> the sweep metric whose log10 is drawn
    "log10 max|violation|": "max_violation",
    "log10 max|ΔE| (energy error)": "max_abs_energy_drift",
}
LOG_FLOOR = 1e-16  # an exact zero (round-off level and below) is drawn as −16, as in the plots
NO_CELL = "(compute the map first)"


class _Stale(Exception):
    """The study was superseded (a new one, another scene, the browser left)."""


@dataclass
class StudyGrid:
    """A computed map: the axes, the runs' rows, and the settings it was computed with."""

    kind: str  # the page view's kind
    gain: str  # "gamma" | "gamma1" | "gamma2"
    gains: tuple[float, ...]
    log_dts: tuple[float, ...]  # log10 of the step sizes, half a decade apart
    dts: tuple[float, ...]  # dt_of(log_dts): the step sizes run
    base: dict  # the settings every run shares
    rows: list[dict] = field(default_factory=list)
    columns: list[str] = field(default_factory=list)

    def z(self, metric: str) -> np.ndarray:
        """log10 of the metric over the grid, shape (len(dts), len(gains)), floored at
        log10(:data:`LOG_FLOOR`); NaN where a run was not ok (or a system has no constraint)."""
        raw = metric_values(self.rows, METRICS[metric], self.columns) if self.rows else []
        vals = [math.log10(max(abs(v), LOG_FLOOR)) if math.isfinite(v) else v for v in raw]
        z = np.full((len(self.dts), len(self.gains)), np.nan)
        ig, idt = {g: i for i, g in enumerate(self.gains)}, {d: i for i, d in enumerate(self.dts)}
        for r, v in zip(self.rows, vals, strict=True):
            z[idt[r["dt"]], ig[r[self.gain]]] = v
        return z

    def status(self) -> dict[tuple[int, int], str]:
        """(dt index, gain index) → status of every run that did not end ``ok``."""
        ig, idt = {g: i for i, g in enumerate(self.gains)}, {d: i for i, d in enumerate(self.dts)}
        return {(idt[r["dt"]], ig[r[self.gain]]): r["status"] for r in self.rows if r["status"] != "ok"}

    def cells(self) -> list[tuple[int, int]]:
        """Every cell (dt index, gain index), in the Cell dropdown's order."""
        return [(j, i) for j in range(len(self.dts)) for i in range(len(self.gains))]

    def label(self, cell: tuple[int, int], metric: str) -> str:
        j, i = cell
        v = self.z(metric)[j, i]
        what = f"{v:.2f}" if math.isfinite(v) else self.status().get(cell, "—")
        return f"{GAIN_FIELDS[self.gain]} = {self.gains[i]:g} · Δt = {self.dts[j]:g} → {what}"

    def best(self, metric: str) -> tuple[int, int] | None:
        z = self.z(metric)
        if not np.isfinite(z).any():
            return None
        j, i = np.unravel_index(np.nanargmin(z), z.shape)
        return int(j), int(i)


def study_axes(controls, gain: str, log_dt_now: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """The gains (N_GAIN values from the gain slider's minimum to 0, on its step) and log10
    of the step sizes (N_DT, half a decade apart, centred on ``log_dt_now`` inside the Δt
    slider's range) of a study; ``controls`` are the page view's :class:`~web.controls.Control` rows."""
    c = next((c for c in controls if c.field == gain), None)
    if c is None:
        raise ValueError(f"this system has no {gain} control")
    hi = min(c.max, 0.0)
    step = c.step or 1e-9
    gains = tuple(float(round(round(g / step) * step, 10)) for g in np.linspace(c.min, hi, N_GAIN))
    lo_dt, hi_dt = (math.log10(v) for v in DT_RANGE)
    half = 0.5 * (N_DT - 1) * 0.5
    centre = min(max(float(log_dt_now), lo_dt + half), hi_dt - half)
    log_dts = tuple(round(centre + 0.5 * (k - (N_DT - 1) / 2), 2) for k in range(N_DT))
    return tuple(dict.fromkeys(gains)), log_dts


def study_grid(kind: str, controls: dict, read, system, gain: str, horizon: float) -> StudyGrid:
    """The study of a page view: ``controls`` maps Control → handle, ``read(handle)`` its value,
    ``system`` the core System; the base settings are the page's, over ``horizon`` seconds."""
    settings, _ = settings_from(system, controls, read)
    gains, log_dts = study_axes(tuple(controls), gain, math.log10(settings["dt"]))
    dts = tuple(dt_of(v) for v in log_dts)
    t_final = min(float(settings["t_final"]), float(horizon))
    base = {**settings, "t_final": t_final, "every": max(1, round(t_final / min(dts) / ROWS_PER_RUN))}
    return StudyGrid(kind, gain, gains, log_dts, dts, base)


def render(grid: StudyGrid, metric: str, cell: tuple[int, int] | None = None, title: str = "") -> np.ndarray:
    """The map as an RGBA image: the metric over gain (x) × Δt (y), values written in the cells."""
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    z = grid.z(metric)
    fig = Figure(figsize=(4.6, 3.5), dpi=100)
    ax = fig.add_subplot()
    cmap = matplotlib.colormaps["viridis"].with_extremes(bad="#bbbbbb")
    im = ax.imshow(np.ma.masked_invalid(z), origin="lower", aspect="auto", cmap=cmap)
    fig.colorbar(im, ax=ax, label=metric)
    bad = grid.status()
    lo, hi = im.get_clim()
    for j in range(len(grid.dts)):
        for i in range(len(grid.gains)):
            v = float(z[j, i])
            light = not math.isfinite(v) or v - lo > 0.6 * (hi - lo)  # dark text on the yellow end and on grey
            text = f"{v:.1f}" if math.isfinite(v) else bad.get((j, i), "")
            size = 6.5 if math.isfinite(v) else 5.5  # a status word is longer than a number
            ax.text(i, j, text, ha="center", va="center", fontsize=size, color="k" if light else "w")
    if cell is not None:
        ax.add_patch(Rectangle((cell[1] - 0.5, cell[0] - 0.5), 1, 1, fill=False, ec="red", lw=2.5))
    ax.set_xticks(range(len(grid.gains)), [f"{g:g}" for g in grid.gains], fontsize=8)
    ax.set_yticks(range(len(grid.dts)), [f"{d:g}" for d in grid.dts], fontsize=8)
    ax.set_xlabel(f"{GAIN_FIELDS[grid.gain]} ({grid.gain})")
    ax.set_ylabel("Δt [s]")
    ax.set_title(title, fontsize=8)
    fig.tight_layout()
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.array(canvas.buffer_rgba(), dtype=np.uint8)


def _title(grid: StudyGrid) -> str:
    st = grid.base
    return f"{st['system']} · {st.get('integrator', '')} · horizon {st['t_final']:g} s"


class _Sink:
    """run_sweep's output for a study: rows kept in the grid, the progress bar moved; a
    superseded study stops at its next batch."""

    def __init__(self, panel: StudyPanel, grid: StudyGrid, gen: int, n: int):
        self.panel, self.grid, self.gen, self.n = panel, grid, gen, n
        self.done: set = set()  # nothing to resume

    def write(self, rows) -> None:
        panel = self.panel
        panel._check(self.gen)
        self.grid.rows.extend(rows)
        with panel.app.lock:
            panel._check(self.gen)
            panel.progress.value = min(100.0, 100.0 * len(self.grid.rows) / self.n)


class StudyPanel:
    """The panel's handles and its background study, for one session ``app`` (a
    :class:`web.session.MechanismApp`: its ``system_view``, ``sim_controls``, ``controls``,
    ``lock``, ``alive()``, ``runner`` and ``request()`` are used).  Build it inside a GUI
    folder after the session's own wiring; it follows the scene dropdown by itself."""

    def __init__(self, gui, app):
        self.app = app
        self.grid: StudyGrid | None = None
        self.thread: threading.Thread | None = None
        self.error: str | None = None
        self._gen = 0
        self._quiet = False
        self._cells: dict[str, tuple[int, int]] = {}
        gui.add_markdown(
            f"A map of the step size Δt against a Baumgarte gain for the settings above: "
            f"{N_GAIN}×{N_DT} short runs in the background. Pick a cell to load its gain and Δt."
        )
        self.gain = gui.add_dropdown("Gain (x axis)", options=("Γ",), initial_value="Γ")
        self.metric = gui.add_dropdown("Colour", options=tuple(METRICS), initial_value=next(iter(METRICS)))
        self.horizon = app.controls.number("Horizon [s]", HORIZON_S, 0.05, 60.0, 0.05, unit="s", slider=False)
        self.compute_button = gui.add_button("Compute the map")
        self.progress = gui.add_progress_bar(0.0, visible=False)
        self.note = gui.add_markdown("")
        self.image = gui.add_image(np.full((2, 2, 4), 255, np.uint8), format="png", visible=False)
        self.cell = gui.add_dropdown("Cell", options=(NO_CELL,), initial_value=NO_CELL)
        self.load_button = gui.add_button("Load cell into the sliders")
        self.best_button = gui.add_button("Load best cell")
        self.compute_button.on_click(lambda _: self.start())
        self.metric.on_update(lambda _: self._redraw())
        self.cell.on_update(lambda _: self._redraw())
        self.load_button.on_click(lambda _: self.load(self._cells.get(self.cell.value)))
        self.best_button.on_click(lambda _: self.load_best())
        app.scene_choice.on_update(lambda _: self.follow_scene())
        self.follow_scene()

    # ---------------------------------------------------------------- choices
    def gain_fields(self) -> list[str]:
        """The gains the page's current system has sliders for."""
        fields = {c.field for c in self.app.sim_controls[self.app.kind]}
        return [f for f in GAIN_FIELDS if f in fields]

    def follow_scene(self) -> None:
        """Another system on the page: its gains in the chooser; the old map is dropped."""
        self._gen += 1
        labels = tuple(GAIN_FIELDS[f] for f in self.gain_fields()) or ("(no gain)",)
        self.gain.options = labels
        if self.gain.value not in labels:
            self.gain.value = labels[0]
        self.grid = None
        self.image.visible = self.progress.visible = False
        self._set_cells([])
        self.note.content = "" if self.gain_fields() else "(this system has no Baumgarte gain to study)"

    # ---------------------------------------------------------------- the study
    def start(self) -> threading.Thread | None:
        """Start a study of the page's current settings in the background (a running one is dropped)."""
        app = self.app
        by_label = {v: k for k, v in GAIN_FIELDS.items()}
        gain = by_label.get(self.gain.value)
        if gain not in self.gain_fields():
            self.note.content = "(this system has no Baumgarte gain to study)"
            return None
        view = app.system_view
        horizon = float(self.horizon.value)  # the box refuses what is not a number in its range
        grid = study_grid(view.kind, app.sim_controls[view.kind], app.controls.value, view.core, gain, horizon)
        self._gen += 1
        gen = self._gen
        self.grid, self.error = None, None
        self._set_cells([])
        self.progress.value, self.progress.visible = 0.0, True
        n = len(grid.gains) * len(grid.dts)
        self.note.content = f"computing {n} runs of {grid.base['t_final']:g} s …"
        self.thread = threading.Thread(target=self._run, args=(grid, gen), daemon=True, name="nmkane-study")
        self.thread.start()
        return self.thread

    def _check(self, gen: int) -> None:
        if gen != self._gen or not self.app.alive():
            raise _Stale

    def _run(self, grid: StudyGrid, gen: int) -> None:
        """The study's thread: the sweep, then the map (or the failure) on the panel."""
        from nmkane_core.sweep.output import columns
        from nmkane_core.sweep.runner import constraint_columns

        spec = SweepSpec(axes=[Axis(grid.gain, grid.gains), Axis("dt", grid.dts)])
        try:
            grid.columns = columns(spec.names, constraint_columns(grid.base, spec))
            with SerialExecutor(time_limit=TIME_LIMIT_S) as ex:
                res = run_sweep(grid.base, spec, _Sink(self, grid, gen, len(spec)), executor=ex, progress=False)
        except _Stale:
            return
        except Exception as e:  # a teaching aid never takes the session down
            with self.app.lock:
                if gen == self._gen and self.app.alive():
                    self.error = f"{type(e).__name__}: {e}"
                    self.progress.visible = False
                    self.note.content = f"⚠ the study failed: {self.error}"
            return
        metric = self.metric.value
        img = render(grid, metric, grid.best(metric), _title(grid))  # drawn outside the session lock
        with self.app.lock:
            if gen == self._gen and self.app.alive():
                self._show(grid, res, img)

    def _show(self, grid: StudyGrid, res, img: np.ndarray) -> None:
        """A finished study on the panel: the note, the cells, the map."""
        self.grid = grid
        counts = ", ".join(f"{v} {k}" for k, v in sorted(res.statuses.items()))
        self.note.content = (
            f"{res.ran} runs in {res.wall_s:.1f} s ({counts}); horizon {grid.base['t_final']:g} s, "
            f"{grid.base.get('integrator', '')}. Grey: the run did not end ok."
        )
        self.progress.visible = False
        self._quiet = True  # the cell dropdown's callback would draw the map again
        try:
            self._set_cells(grid.cells())
        finally:
            self._quiet = False
        self.image.image = img
        self.image.visible = True

    def wait(self, timeout: float = 120.0) -> bool:
        """Wait for the running study (tests); True when none is left running."""
        t = self.thread
        if t is not None:
            t.join(timeout)
        return t is None or not t.is_alive()

    # ---------------------------------------------------------------- cells
    def _set_cells(self, cells: list[tuple[int, int]]) -> None:
        grid = self.grid
        if grid is None or not cells:
            self._cells = {}
            self.cell.options = (NO_CELL,)
            self.cell.value = NO_CELL
            return
        metric = self.metric.value
        self._cells = {grid.label(c, metric): c for c in cells}
        self.cell.options = tuple(self._cells)
        best = grid.best(metric)
        self.cell.value = grid.label(best, metric) if best is not None else next(iter(self._cells))

    def _redraw(self) -> None:
        """Draw the map for the chosen metric with the chosen cell marked (a metric change
        relabels the cells: the same cell stays chosen under its new label)."""
        grid = self.grid
        if grid is None or self._quiet:
            return
        metric = self.metric.value
        cell = self._cells.get(self.cell.value)
        if cell is not None and self.cell.value != grid.label(cell, metric):
            self._quiet = True
            try:
                self._cells = {grid.label(c, metric): c for c in grid.cells()}
                self.cell.options = tuple(self._cells)
                self.cell.value = grid.label(cell, metric)
            finally:
                self._quiet = False
        img = render(grid, metric, cell, _title(grid))
        if self.app.alive():
            self.image.image = img
            self.image.visible = True

    def load(self, cell: tuple[int, int] | None) -> bool:
        """Put a cell's gain and Δt into the page's sliders (one re-simulation); False if there
        is no map, or it belongs to another system than the one on the page."""
        grid, app = self.grid, self.app
        if grid is None or cell is None:
            self.note.content = "(compute the map first)"
            return False
        if grid.kind != app.kind:
            self.note.content = "(the map is of another system: compute it again)"
            return False
        j, i = cell
        handles = {c.field: h for c, h in app.sim_controls[grid.kind].items()}
        app.runner.quiet = True
        try:
            handles[grid.gain].value = grid.gains[i]
            if "dt" in handles:  # every view has one; a view without keeps its Δt
                handles["dt"].value = grid.dts[j]
        finally:
            app.runner.quiet = False
        app.request()
        label = grid.label(cell, self.metric.value)
        if self.cell.value != label and label in self._cells:
            self.cell.value = label
        return True

    def load_best(self) -> bool:
        grid = self.grid
        return self.load(None if grid is None else grid.best(self.metric.value))
