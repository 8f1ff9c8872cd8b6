"""Plot data for viser's uPlot widgets (pure numpy): decimation that keeps the extremes,
readable units for tiny values, and the current-time marker.

A plot's curves are computed and sent once per trajectory (:class:`Curves`).  The
current-time marker is the grid line of a hidden second x axis whose only split is t_now
(:func:`marker_axes`): moving it sends a few hundred bytes instead of the curves again
(tested in Chromium).  No NaN is ever sent (tested: a NaN in a series breaks uPlot's
auto-range and the whole curve disappears), so exact zeros on the log scale sit at the
floor, 1e−16.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")  # one per constraint
RUN_COLORS = ("#1f77b4", "#ff7f0e", "#9467bd", "#2ca02c")  # the shown run, then the compare runs (ghosts)
RUN_COLOR_NAMES = ("blue", "orange", "purple", "green")  # as the legend and the scene name them
DASHES = ((6.0, 4.0), (2.0, 3.0), (10.0, 3.0, 2.0, 3.0))  # compare runs: dashed, one pattern each
DASH_NAMES = ("dashed", "dotted", "dash-dot")
MAX_POINTS = 800  # per series after decimation (two per bucket: min and max)
LOG_FLOOR = 1e-16  # |φ| below this is plotted as 1e-16 (round-off level)
#: uPlot padding (top, right, bottom, left) in px.  viser's default top is 0, and the hidden
#: marker axis on top (:func:`marker_axes`) stops uPlot from adding its own, so the top y tick's
#: label (12 px, centred on its tick) lost its upper half; 10 px hold it whole.
PADDING = (10, 24, 0, 0)
#: a series whose spread is at most this fraction of its size is drawn as a constant
CONSTANT_REL = 1e-12


def envelope(t: np.ndarray, ys: list[np.ndarray], max_points: int = MAX_POINTS):
    """Min/max decimation: each of ≤ max_points/2 buckets of samples contributes its minimum
    and maximum (at the bucket's first and last time), so spikes and oscillation envelopes
    survive thinning."""
    t = np.asarray(t, float)
    n = len(t)
    if n <= max_points:
        return t, [np.asarray(y, float) for y in ys]
    buckets = max_points // 2
    edges = np.linspace(0, n, buckets + 1).round().astype(int)
    lo, hi = edges[:-1], edges[1:] - 1
    t_out = np.empty(2 * buckets)
    t_out[0::2], t_out[1::2] = t[lo], t[hi]
    out = []
    for y in ys:
        y = np.asarray(y, float)
        mn = np.minimum.reduceat(y, edges[:-1])
        mx = np.maximum.reduceat(y, edges[:-1])
        yy = np.empty(2 * buckets)
        yy[0::2], yy[1::2] = mn, mx
        out.append(yy)
    return t_out, out


def log10_abs(v: np.ndarray) -> np.ndarray:
    """log10|v| floored at log10(1e-16) (exact zeros included)."""
    a = np.nan_to_num(np.abs(np.asarray(v, float)), nan=1e300, posinf=1e300)
    return np.log10(np.maximum(a, LOG_FLOOR))


def readable(values: list[np.ndarray], unit: str) -> tuple[float, str]:
    """A power-of-ten factor and a label unit so tick labels are not "0 0 0" (uPlot shows
    values near 1e-4 and below as 0): returns (divide_by, "×1e-9 J")."""
    big = max((float(np.abs(v).max()) for v in values if len(v)), default=0.0)
    if big == 0.0 or 1e-2 <= big < 1e5:
        return 1.0, unit
    e = math.floor(math.log10(big))
    return 10.0**e, f"×1e{e} {unit}".strip()


def constant_range(ys) -> tuple[float, float] | None:
    """The y range of series that are one constant c (within round-off): c ± 1 for c = 0 (uPlot
    would run 0–100), else c ± |c|/10; None when the series vary (uPlot's own auto range)."""
    vals = [np.asarray(y, float) for y in ys]
    vals = [v[np.isfinite(v)] for v in vals]
    vals = [v for v in vals if len(v)]
    if not vals:
        return None
    lo, hi = min(float(v.min()) for v in vals), max(float(v.max()) for v in vals)
    big = max(abs(lo), abs(hi))
    if hi - lo > CONSTANT_REL * big:
        return None
    c = 0.5 * (lo + hi)
    h = 1.0 if big == 0.0 else 0.1 * big
    return c - h, c + h


@dataclass
class Curves:
    """One plot's decimated curves: t and one array per series (without the marker), the
    axis titles, and the whole-resolution curves a time window is cut from."""

    t: np.ndarray
    ys: list[np.ndarray]
    labels: list[str]
    styles: list[dict] = field(default_factory=list)  # uPlot series styles (stroke, dash), one per series
    y_label: str = ""
    x_label: str = "t [s]"
    full: tuple[np.ndarray, list[np.ndarray]] | None = None  # (t, ys) before decimation

    def data(self) -> tuple[np.ndarray, ...]:
        """uPlot's data: (t, y1, …, yn)."""
        return (self.t, *self.ys)

    def window(self, t0: float, t1: float) -> tuple[np.ndarray, ...]:
        """uPlot's data for the rows with t0 ≤ t ≤ t1 (decimated again, so a long run's
        window shows its oscillations instead of their envelope)."""
        if self.full is None:
            return self.data()
        t, ys = self.full
        i0 = max(0, int(np.searchsorted(t, t0, side="left")) - 1)
        i1 = min(len(t), int(np.searchsorted(t, t1, side="right")) + 1)
        if i1 - i0 < 2:
            return self.data()
        td, yd = envelope(t[i0:i1], [y[i0:i1] for y in ys])
        return (td, *yd)


def marker_axes(t_now: float, x_label: str = "t [s]", y_label: str = "") -> tuple[dict, ...]:
    """uPlot axes: the x and y axes with their titles (the y axis wide enough for labels such
    as −0.002), plus a hidden top x axis whose single grid line at t_now is the current-time
    marker."""
    return (
        {"scale": "x", "label": x_label, "labelSize": 18, "size": 36},
        {"label": y_label, "labelSize": 18, "size": 68, "gap": 4},
        {
            "scale": "x",
            "side": 0,
            "size": 0,
            "splits": (float(t_now),),
            "values": ("",),
            "ticks": {"show": False},
            "grid": {"show": True, "stroke": "#444444", "width": 1.5, "dash": (4.0, 3.0)},
        },
    )


def curves(t, ys, labels, max_points: int = MAX_POINTS, y_label: str = "") -> Curves:
    """Decimated curves for one plot; non-finite samples are clipped (never sent as NaN)."""
    ys = [np.nan_to_num(np.asarray(y, float), nan=0.0, posinf=1e300, neginf=-1e300) for y in ys]
    t = np.asarray(t, float)
    td, yd = envelope(t, ys, max_points)
    return Curves(td, yd, list(labels), y_label=y_label, full=(t, ys))
