"""Plot data for viser's uPlot widgets (pure numpy): decimation that keeps the extremes,
readable units for tiny values, the current-time marker, axes wide enough for their tick
labels, and the ranges of a phase portrait (equal scales when its two axes share a unit).

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

# ---------------------------------------------------------------- the page's plots, in pixels
#: the plots' shape: viser makes a uPlot as wide as the panel and ``width / ASPECT`` high (axes
#: included; the title and legend are outside)
ASPECT = 1.6
#: a plot's width in the page (viser's "large" control panel, measured in Chromium at 1280 and
#: 1400 px) until the page reports its own (:meth:`web.panel.PlotPanel.set_width`)
PLOT_WIDTH_PX = 345.0
X_AXIS_PX = 36  # the x axis (ticks and values)
Y_AXIS_PX = 68  # the y axis at least (ticks and values, e.g. −0.002)
TITLE_PX = 18  # the strip of an axis' title (uPlot's labelSize)
TICK_PX = 10  # uPlot's tick length
Y_GAP_PX = 4  # between a y tick and its value
X_GAP_PX = 5  # between an x tick and its value (uPlot's default)
#: widths (px) of the characters of tick values in uPlot's axis font (12 px system-ui): DejaVu Sans,
#: the widest of the usual system fonts (what Debian's Chromium draws with); digits and the rest
CHAR_PX = {".": 3.82, ",": 3.82, "-": 4.34, " ": 3.82}
DIGIT_PX = 7.64
Y_SPACE_PX = 30  # uPlot's least spacing between y ticks (its default)
X_SPACE_PX = 50  # … between x ticks
PHASE_MARGIN = 0.06  # a phase portrait's data box takes 1/(1 + 2·margin) of each axis at most


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
    finite = [a[np.isfinite(a)] for a in (np.abs(np.asarray(v, float)) for v in values)]
    big = max((float(a.max()) for a in finite if len(a)), default=0.0)
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


def text_px(text: str) -> float:
    """The width in pixels of a tick value in uPlot's axis font (see :data:`CHAR_PX`)."""
    return sum(CHAR_PX.get(c, DIGIT_PX) for c in text)


def tick_value(v: float) -> str:
    """A tick value as uPlot writes it (``Intl.NumberFormat``'s default: grouped thousands, at
    most three decimals, no trailing zeros)."""
    text = f"{v:,.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def increment(lo: float, hi: float, px: float, space: float) -> float:
    """uPlot's tick increment for [lo, hi] drawn over ``px`` pixels: the smallest of 1, 2, 2.5,
    5 × 10^k whose ticks are at least ``space`` pixels apart."""
    span = hi - lo
    if not (span > 0 and math.isfinite(span)):
        return 1.0
    least = span * space / max(px, 1.0)
    e = math.floor(math.log10(least))
    for k in (e, e + 1):
        for m in (1.0, 2.0, 2.5, 5.0):
            if m * 10.0**k >= least * (1 - 1e-12):
                return m * 10.0**k
    return 10.0 ** (e + 2)


def tick_values(lo: float, hi: float, px: float, space: float = Y_SPACE_PX) -> list[str]:
    """The tick values uPlot writes on an axis showing [lo, hi] over ``px`` pixels."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi <= lo:
        return [tick_value(lo if math.isfinite(lo) else 0.0)]
    incr = increment(lo, hi, px, space)
    first, last = math.ceil(lo / incr - 1e-9), math.floor(hi / incr + 1e-9)
    if last - first > 200:  # not an axis uPlot would draw: its two ends then
        return [tick_value(lo), tick_value(hi)]
    return [tick_value(k * incr) for k in range(first, last + 1)]


def auto_range(lo: float, hi: float) -> tuple[float, float]:
    """About the range uPlot's automatic y scale gives data in [lo, hi] (a tenth of the span
    more each side, reaching 0 when it is near)."""
    span = hi - lo
    lo2, hi2 = lo - 0.1 * span, hi + 0.1 * span
    if lo >= 0 >= lo2:
        lo2 = 0.0
    if hi <= 0 <= hi2:
        hi2 = 0.0
    return lo2, hi2


def y_axis_px(lo: float, hi: float, height_px: float = 150.0) -> int:
    """How wide the y axis must be for the tick values of [lo, hi] (at least :data:`Y_AXIS_PX`):
    the widest value, its tick and gap, and two pixels to spare."""
    widest = max((text_px(v) for v in tick_values(lo, hi, height_px)), default=0.0)
    return max(Y_AXIS_PX, math.ceil(widest + TICK_PX + Y_GAP_PX + 2))


def data_range(ys) -> tuple[float, float] | None:
    """(lowest, highest) finite value of the series (None when there is none)."""
    vals = [np.asarray(y, float) for y in ys]
    vals = [v[np.isfinite(v)] for v in vals]
    vals = [v for v in vals if len(v)]
    if not vals:
        return None
    return min(float(v.min()) for v in vals), max(float(v.max()) for v in vals)


def plot_box(width: float, y_axis: int = Y_AXIS_PX, padding=PADDING) -> tuple[float, float]:
    """The pixel box a uPlot ``width`` pixels wide draws its data in (its width and height),
    with a y axis ``y_axis`` wide and the page's padding (top, right, bottom, left)."""
    top, right, bottom, left = padding
    return (
        width - (y_axis + TITLE_PX) - right - left,
        width / ASPECT - (X_AXIS_PX + TITLE_PX) - top - bottom,
    )


def marker_axes(t_now: float, x_label: str = "t [s]", y_label: str = "", y_axis: int = Y_AXIS_PX) -> tuple[dict, ...]:
    """uPlot axes: the x and y axes with their titles (the y axis ``y_axis`` pixels wide: see
    :func:`y_axis_px`), plus a hidden top x axis whose single grid line at t_now is the
    current-time marker."""
    return (
        {"scale": "x", "label": x_label, "labelSize": TITLE_PX, "size": X_AXIS_PX},
        {"label": y_label, "labelSize": TITLE_PX, "size": int(y_axis), "gap": Y_GAP_PX},
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


# ---------------------------------------------------------------- phase portraits
#: the grid line of a hidden axis marking the current point (as the time plots' marker)
MARKER_GRID = {"show": True, "stroke": "#444444", "width": 1.5, "dash": (4.0, 3.0)}


def padded(lo: float, hi: float, margin: float = PHASE_MARGIN) -> tuple[float, float]:
    """An axis range holding [lo, hi] strictly inside, ``margin`` of the span more each side; a
    constant c gets :func:`constant_range`'s axis (c ± 1 for 0, else c ± |c|/10)."""
    big = max(abs(lo), abs(hi))
    if not hi - lo > CONSTANT_REL * big:
        c = 0.5 * (lo + hi)
        h = 1.0 if big == 0.0 else 0.1 * big
        return c - h, c + h
    pad = margin * (hi - lo)
    return lo - pad, hi + pad


def equal_ranges(
    x: tuple[float, float], y: tuple[float, float], box: tuple[float, float], margin: float = PHASE_MARGIN
) -> tuple[tuple[float, float], tuple[float, float]]:
    """x and y ranges showing the data box x × y whole and centred in a plot box of ``box`` =
    (width, height) pixels with *equal scales*: as many units per pixel across as up (a circle
    is drawn round).  The data take 1/(1 + 2·margin) of the axis they fill; a single point gets
    the axes a constant would (:func:`padded`)."""
    (x_lo, x_hi), (y_lo, y_hi) = x, y
    w, h = max(box[0], 1.0), max(box[1], 1.0)
    big = max(abs(x_lo), abs(x_hi), abs(y_lo), abs(y_hi))
    flat = CONSTANT_REL * big  # a spread within round-off is none
    sx = x_hi - x_lo if x_hi - x_lo > flat else 0.0
    sy = y_hi - y_lo if y_hi - y_lo > flat else 0.0
    per_px = max(sx / w, sy / h) * (1 + 2 * margin)
    if per_px == 0.0:
        per_px = 2 * (1.0 if big == 0.0 else 0.1 * big) / min(w, h)
    cx, cy = 0.5 * (x_lo + x_hi), 0.5 * (y_lo + y_hi)
    return (cx - per_px * w / 2, cx + per_px * w / 2), (cy - per_px * h / 2, cy + per_px * h / 2)


def phase_axes(x_now: float, y_now: float, x_label: str, y_label: str, y_axis: int = Y_AXIS_PX) -> tuple[dict, ...]:
    """uPlot axes of a phase portrait: x and y with their titles, and two hidden axes whose
    grid lines cross at the current point (x_now, y_now)."""
    marker = {"size": 0, "values": ("",), "ticks": {"show": False}, "grid": MARKER_GRID}
    return (
        {"scale": "x", "label": x_label, "labelSize": TITLE_PX, "size": X_AXIS_PX},
        {"scale": "y", "label": y_label, "labelSize": TITLE_PX, "size": int(y_axis), "gap": Y_GAP_PX},
        {"scale": "x", "side": 0, "splits": (float(x_now),), **marker},
        {"scale": "y", "side": 1, "splits": (float(y_now),), **marker},
    )


def x_padding(x_range: tuple[float, float], box_w: float) -> tuple[int, int, int, int]:
    """The page's padding, with room at the right for half the widest x tick value (a value
    centred on a tick at the plot's right edge)."""
    widest = max((text_px(v) for v in tick_values(*x_range, box_w, X_SPACE_PX)), default=0.0)
    top, right, bottom, left = PADDING
    return top, max(right, math.ceil(widest / 2) + 2), bottom, left
