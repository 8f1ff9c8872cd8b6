"""The eigenvalues-versus-swept-value plot of a system that declares a stability sweep
(``System(stability=Stability(...))``, :mod:`nmkane_core.declare.stability`): real and imaginary
parts of the linearized motion's eigenvalues against the swept value (e.g. a forward speed),
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
IMAG_COLOR = "#555555"  # max |Im λ|, dashed (the real parts take the plots' colours, one each)
YMAX = 10.0  # the y range shown, ±1/s (Meijaard et al. 2007, Fig. 3)


class StabilityPlot:
    """One system's eigenvalue plot (one per view and browser)."""

    def __init__(self, gui, core, order: float | None = None):
        self.core = core
        self.st = core.stability
        self.params_key: tuple | None = None
        self.value = 0.0
        self._lock = threading.Lock()
        n = len(self.st.keep)
        z = np.zeros(2)
        series = [uplot.Series(label=f"{self.st.over} [{self.st.unit}]")]
        series += [
            uplot.Series(label=f"Re λ{i + 1} [1/s]", stroke=pl.COLORS[i % len(pl.COLORS)], width=1.8) for i in range(n)
        ]
        series.append(uplot.Series(label="max |Im λ| [1/s], dashed", stroke=IMAG_COLOR, width=1.5, dash=(5.0, 3.0)))
        self.x_label = f"{self.st.over} [{self.st.unit}]"
        self.handle = gui.add_uplot(
            order=order,
            data=(z,) * (n + 2),
            series=tuple(series),
            title=f"Eigenvalues against {self.st.over} (current marked)",
            scales={
                "x": uplot.Scale(time=False, auto=False, range=(self.st.start, self.st.stop)),
                "y": uplot.Scale(auto=False, range=(-YMAX, YMAX)),
            },
            axes=pl.marker_axes(0.0, f"{self.st.over} [{self.st.unit}]", "eigenvalues [1/s]"),
            aspect=1.4,
            visible=False,
        )

    @staticmethod
    def data(rows: list[dict]) -> tuple[np.ndarray, ...]:
        """uPlot data: the swept values, the real parts sorted (each a continuous curve of
        the value) and the largest imaginary part (0 where every eigenvalue is real), all
        finite and clipped just outside the plot's y range (uPlot drops a series holding a NaN)."""
        x = np.array([r["value"] for r in rows], float)
        ev = np.array([[complex(a, b) for a, b in r["eigenvalues"]] for r in rows])
        re = np.sort(ev.real, axis=1)
        im = np.abs(ev.imag).max(axis=1)
        clip = lambda a: np.clip(np.nan_to_num(a, nan=0.0), -1.2 * YMAX, 1.2 * YMAX)  # noqa: E731
        return (x, *[clip(re[:, j]) for j in range(re.shape[1])], clip(im))

    def update(self, params: dict, initial: dict) -> None:
        """Mark the value of a run with ``initial`` values; recompute the sweep (in a thread)
        when ``params`` changed since the last one."""
        try:
            values = self.core.resolve_params(params)
            if self.st.value_of is not None:
                self.value = float(self.st.value_of(initial, values))
        except Exception:  # a marker is not worth an error on the page
            return
        self.handle.axes = pl.marker_axes(self.value, self.x_label, "eigenvalues [1/s]")
        key = tuple(sorted(values.items()))
        with self._lock:
            if key == self.params_key:
                return
            self.params_key = key
        threading.Thread(target=self._compute, args=(values, key), daemon=True).start()

    def _compute(self, values: dict, key: tuple) -> None:
        from nmkane_core.analysis.eigensweep import sweep

        try:
            rows = sweep(self.core, None, values)
        except Exception:
            return
        with self._lock:
            if key != self.params_key:
                return  # parameters changed meanwhile: the newer thread draws
        self.handle.data = self.data(rows)
        self.handle.axes = pl.marker_axes(self.value, self.x_label, "eigenvalues [1/s]")


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
