"""Plots that do not mislead (issue 43, item 5): a phase portrait of two lengths is drawn to
equal scale (the knife edge's circle of radius v/ω is round, not a 2:1 ellipse); a constant
series gets a small axis around its value (ΔE ≡ 0 does not run 0–100 J); tick values are
neither "0 0 0" nor wider than their axis; the top tick's label is not cut off.  No browser:
the ranges, the uPlot options and the data are checked (tests/web/test_plots_browser.py looks
at the drawn charts)."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from nmkane_core import simulate
from web import curves as cv
from web import plots as pl
from web.panel import PHASE_POINTS_PER_PX, PlotPanel


@pytest.fixture(scope="module")
def knife_edge():
    return simulate({"system": "knife-edge", "t_final": 20})  # v = 1, ω = 0.5: a circle of radius 2


class FakeGui:
    def __init__(self):
        self.plots: list[dict] = []

    def add_markdown(self, content):
        return SimpleNamespace(content=content)

    def add_uplot(self, **kw):
        self.plots.append(kw)
        return SimpleNamespace(**kw)


class FakeView:
    kind = "knife-edge"
    plots = (("energy", "Energy drift ΔE(t)"), ("violation", "log₁₀ |φ|"), ("coord", "Plotted quantity"))

    def series_style(self, key, i, traj):
        return {}


def per_pixel(x_range, y_range, box):
    """Units per pixel across and up."""
    return (x_range[1] - x_range[0]) / box[0], (y_range[1] - y_range[0]) / box[1]


@pytest.mark.parametrize("width", [345.0, 300.0, 520.0, 900.0])
def test_the_knife_edges_circle_gets_equal_scales_in_the_plots_pixel_box(knife_edge, width):
    phase = cv.quantity({"default": knife_edge}, "y", "x")
    assert isinstance(phase, cv.Phase) and phase.equal  # x and y place the blade: both lengths
    (x_lo, x_hi), (y_lo, y_hi) = phase.box()
    assert x_hi - x_lo == pytest.approx(4.0, rel=1e-3) and y_hi - y_lo == pytest.approx(4.0, rel=1e-3)
    panel = PlotPanel(FakeGui(), {"knife-edge": FakeView()})
    panel.width = width
    xr, yr, y_axis, padding = panel.phase_layout(phase)
    box = pl.plot_box(width, y_axis, padding)
    ux, uy = per_pixel(xr, yr, box)
    assert ux == pytest.approx(uy, rel=1e-9)  # a metre as long across as up
    assert xr[0] < x_lo and x_hi < xr[1] and yr[0] < y_lo and y_hi < yr[1]  # the whole circle, strictly inside
    assert max((x_hi - x_lo) / (xr[1] - xr[0]), (y_hi - y_lo) / (yr[1] - yr[0])) > 0.8  # and filling the box


def test_the_plot_box_is_the_one_uplot_draws_in():
    """Measured in Chromium (tests/web/test_plots_browser.py reads it from the chart): a plot 345 px
    wide draws in 235 × 151.6 px."""
    assert pl.plot_box(345.0) == pytest.approx((235.0, 345.0 / 1.6 - 64.0))


def test_a_portrait_of_quantities_of_other_units_keeps_its_own_scales(knife_edge):
    assert not cv.quantity({"default": knife_edge}, "theta", "x").equal  # rad against m
    assert not cv.quantity({"default": knife_edge}, "u1", "x").equal  # m/s against m
    assert not cv.quantity({"default": knife_edge}, "2*y", "x").equal  # an expression: unit unknown
    assert cv.length_coordinates("knife-edge") == frozenset({"x", "y"})
    phase = cv.quantity({"default": knife_edge}, "theta", "x")
    panel = PlotPanel(FakeGui(), {"knife-edge": FakeView()})
    xr, yr, *_ = panel.phase_layout(phase)
    (x_lo, x_hi), (y_lo, y_hi) = phase.box()
    assert (x_hi - x_lo) / (xr[1] - xr[0]) == pytest.approx(1 / 1.12)  # each axis its own, with a margin
    assert (y_hi - y_lo) / (yr[1] - yr[0]) == pytest.approx(1 / 1.12)


def test_equal_scales_share_one_readable_factor(knife_edge):
    """Micrometres across and up: one factor for both axes, named in both titles."""
    tiny = SimpleNamespace(**{k: getattr(knife_edge, k) for k in ("t", "system", "violation", "energy", "summary")})
    tiny.state = {**knife_edge.state, "x": knife_edge.state["x"] * 1e-6, "y": knife_edge.state["y"] * 1e-6}
    phase = cv.quantity({"default": tiny}, "y", "x")
    assert phase.equal and phase.x_label == "x [×1e-6]" and phase.y_label == "y [×1e-6]"
    assert np.ptp(phase.xs[0]) == pytest.approx(4.0, rel=1e-3)


@pytest.mark.parametrize(
    "ranges,box",
    [
        (((0.0, 0.0), (0.0, 0.0)), (235, 151)),
        (((3.0, 3.0), (-2.0, -2.0)), (235, 151)),
        (((0.0, 1.0), (5.0, 5.0)), (200, 150)),
    ],
)
def test_equal_scales_of_a_point_or_a_line_are_finite_and_hold_it(ranges, box):
    xr, yr = pl.equal_ranges(*ranges, box)
    assert all(math.isfinite(v) for v in (*xr, *yr)) and xr[1] > xr[0] and yr[1] > yr[0]
    assert xr[0] < ranges[0][0] <= ranges[0][1] < xr[1] and yr[0] < ranges[1][0] <= ranges[1][1] < yr[1]
    ux, uy = per_pixel(xr, yr, box)
    assert ux == pytest.approx(uy)


def test_phase_data_draws_each_run_on_its_own_stretch(knife_edge):
    """uPlot's aligned mode with x that turns back: one x array (the runs one after the other),
    each run's y NaN outside its stretch, fewer points than 4 per pixel of the plot's width."""
    other = simulate({"system": "knife-edge", "t_final": 20, "initial": {"u1": 0.5}})
    phase = cv.quantity({"a": knife_edge, "b": other}, "y", "x")
    budget = int(PHASE_POINTS_PER_PX * pl.plot_box(pl.PLOT_WIDTH_PX)[0])
    x, ya, yb = cv.phase_data(phase, budget)
    assert len(x) <= budget < 4 * pl.plot_box(pl.PLOT_WIDTH_PX)[0]
    assert np.all(np.isfinite(x))
    a, b = np.isfinite(ya), np.isfinite(yb)
    assert not np.any(a & b) and np.all(a | b)  # each point belongs to one run
    assert np.all(a[: a.sum()]) and np.all(b[a.sum() :])  # run a first, then run b
    single = cv.phase_data(cv.quantity({"a": knife_edge}, "y", "x"), budget)
    assert all(np.all(np.isfinite(v)) for v in single)  # one run: no NaN at all


@pytest.mark.parametrize("value", [0.0, -16.0, 3.5])
def test_a_constant_series_gets_a_small_axis_around_its_value(value):
    lo, hi = pl.constant_range([np.full(50, value), np.full(50, value)])
    assert lo < value < hi and (lo, hi) != (0.0, 100.0)
    assert hi - lo <= max(2.0, 0.2 * abs(value)) + 1e-12
    assert value - lo == pytest.approx(hi - value)  # symmetric: the line in the middle


def test_a_varying_series_keeps_the_automatic_range():
    assert pl.constant_range([np.linspace(0.0, 1e-3, 50)]) is None
    assert pl.constant_range([np.zeros(50), np.full(50, 1e-9)]) is None  # another run differs


def test_energy_drift_identically_zero_is_not_drawn_on_0_to_100_J(knife_edge):
    energy = cv.energy({"default": knife_edge})
    assert not np.any(energy.ys[0])  # the blade's force does no work: ΔE ≡ 0 exactly
    panel = PlotPanel(FakeGui(), {"knife-edge": FakeView()})
    traj = SimpleNamespace(kind="knife-edge", t_end=20.0, plots={"energy": energy}, runs={"default": knife_edge})
    panel.write(traj, 0.0)
    y = panel.handles[("knife-edge", "energy")].scales["y"]
    assert y["auto"] is False and tuple(y["range"]) == (-1.0, 1.0)


def test_the_top_tick_label_of_every_time_plot_has_room_above_the_plot_area():
    gui = FakeGui()
    PlotPanel(gui, {"knife-edge": FakeView()})
    assert len(gui.plots) == 4  # energy, violation, the quantity against t, the phase portrait
    for kw in gui.plots:  # uPlot's axis labels are 12 px, centred on their tick
        assert kw.get("padding") is not None and kw["padding"][0] >= 7, kw["title"]


@pytest.mark.parametrize(
    "v,text", [(0.0, "0"), (-0.5, "-0.5"), (1234.5, "1,234.5"), (-12345.0, "-12,345"), (1e-4, "0"), (0.0025, "0.003")]
)
def test_tick_values_are_written_as_uplot_writes_them(v, text):
    assert pl.tick_value(v) == text


@pytest.mark.parametrize(
    "lo,hi", [(-1.0, 1.0), (0.0, 99999.0), (-12345.6, 98765.4), (99990.0, 99999.5), (-1.2e-3, 3.4e-3), (-17.6, -14.4)]
)
def test_the_y_axis_is_wide_enough_for_its_widest_tick_value(lo, hi):
    size = pl.y_axis_px(lo, hi)
    widest = max(pl.text_px(v) for v in pl.tick_values(lo, hi, 150.0))
    assert size >= widest + pl.TICK_PX + pl.Y_GAP_PX and size >= pl.Y_AXIS_PX


def test_a_quantity_of_long_numbers_is_divided_into_readable_ones(knife_edge):
    """1e6·x (metres to micrometres) plotted against t: its values would be "4,000,000", wider than
    the axis; they are written as 4 with "×1e6" in the axis title, and 1e-12·x not as "0 0 0"."""
    big = cv.quantity({"default": knife_edge}, "1e6*x", "t")
    assert big.y_label == "1e6*x [×1e6]" and np.abs(big.ys[0]).max() == pytest.approx(2.0, rel=1e-3)
    tiny = cv.quantity({"default": knife_edge}, "1e-12*x", "t")
    assert tiny.y_label == "1e-12*x [×1e-12]" and np.abs(tiny.ys[0]).max() == pytest.approx(2.0, rel=1e-3)
    plain = cv.quantity({"default": knife_edge}, "x", "t")
    assert plain.y_label == "x"
