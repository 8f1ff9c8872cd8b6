"""The eigenvalues-versus-swept-value plot of a system that declares a stability sweep
(``System(stability=Stability(...))``, :mod:`nmkane_core.stability`): real and imaginary
parts of the linearized motion's eigenvalues against the swept value (a bicycle's speed),
with the current run's value marked — the classic self-stability picture.

Two hooks from the page: :func:`attach` when a system's view is built (adds the plot under
the view's other plots, shown and hidden with them) and :func:`update` when a trajectory is
installed (marks the run's value; the sweep is recomputed in a background thread only when
the parameters change).
"""

from __future__ import annotations

import threading

import numpy as np
from viser import uplot

from . import plots as pl

KEY = "stability"
COLORS = ("#222222", "#1f77b4")


class StabilityPlot:
    """One system's eigenvalue plot (one per view and browser)."""

    def __init__(self, gui, core, order: float | None = None):
        self.core = core
        self.st = core.stability
        self.params_key: tuple | None = None
        self.value = 0.0
        self._lock = threading.Lock()
        z = np.zeros(2)
        self.handle = gui.add_uplot(
            order=order,
            data=(z, z, z),
            series=(
                uplot.Series(label=f"{self.st.over} [{self.st.unit}]"),
                uplot.Series(label="Re λ", stroke=COLORS[0], width=0, points={"show": True, "size": 3}),
                uplot.Series(label="|Im λ|", stroke=COLORS[1], width=0, points={"show": True, "size": 3}),
            ),
            title=f"Eigenvalues against {self.st.over} (current marked)",
            scales={"x": uplot.Scale(time=False, auto=False, range=(self.st.start, self.st.stop))},
            axes=pl.marker_axes(0.0),
            aspect=1.4,
            visible=False,
        )

    @staticmethod
    def data(rows: list[dict]) -> tuple[np.ndarray, ...]:
        """uPlot data: every eigenvalue is one point (x repeated per eigenvalue, sorted by x);
        the imaginary parts of real eigenvalues are left out (at 0 they would hide the axis)."""
        xs, re, im = [], [], []
        for r in rows:
            for a, b in r["eigenvalues"]:
                xs.append(r["value"])
                re.append(a)
                im.append(abs(b) if abs(b) > 1e-9 else None)
        x = np.asarray(xs, float)
        re_arr = np.clip(np.asarray(re, float), -20.0, 20.0)
        im_arr = np.array([np.nan if v is None else min(v, 20.0) for v in im])
        # uPlot breaks on NaN: real eigenvalues' imaginary parts repeat the real part there
        im_arr = np.where(np.isfinite(im_arr), im_arr, re_arr)
        return x, re_arr, im_arr

    def update(self, params: dict, initial: dict) -> None:
        """Mark the value of a run with ``initial`` values; recompute the sweep (in a thread)
        when ``params`` changed since the last one."""
        try:
            values = self.core.resolve_params(params)
            if self.st.value_of is not None:
                self.value = float(self.st.value_of(initial, values))
        except Exception:  # a marker is not worth an error on the page
            return
        self.handle.axes = pl.marker_axes(self.value)
        key = tuple(sorted(values.items()))
        with self._lock:
            if key == self.params_key:
                return
            self.params_key = key
        threading.Thread(target=self._compute, args=(values, key), daemon=True).start()

    def _compute(self, values: dict, key: tuple) -> None:
        from nmkane_core.eigensweep import sweep

        try:
            rows = sweep(self.core, None, values)
        except Exception:
            return
        with self._lock:
            if key != self.params_key:
                return  # parameters changed meanwhile: the newer thread draws
        self.handle.data = self.data(rows)
        self.handle.axes = pl.marker_axes(self.value)


def attach(session, view) -> None:
    """Add the plot of ``view``'s system, if it declares a stability sweep, to the session's plots
    (``session.plots.handles``, so that it is shown and hidden with the view's other plots)."""
    core = getattr(view, "core", None)
    if core is None or getattr(core, "stability", None) is None:
        return
    plot = StabilityPlot(session.gui, core)
    view.stability_plot = plot
    session.plots.handles[(view.kind, KEY)] = plot.handle
    plot.handle.visible = view.kind == session.kind


def update(session, traj) -> None:
    """Mark the installed trajectory's value on its view's plot (if it has one)."""
    plot = getattr(session.views.get(traj.kind), "stability_plot", None)
    if plot is None:
        return
    run = traj.main
    initial = {k: float(v[0]) for k, v in run.state.items()}
    plot.update(traj.params, initial)
