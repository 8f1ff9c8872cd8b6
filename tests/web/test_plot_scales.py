"""Plots that do not mislead (issue 43, item 5): a phase portrait of two lengths is drawn to
equal scale (the knife edge's circle of radius v/ω is round, not a 2:1 ellipse); a constant
series gets a small axis around its value (ΔE ≡ 0 does not run 0–100 J); the top tick's label
is not cut off.  No browser: the ranges, the uPlot options and the drawn image are checked."""

from types import SimpleNamespace

import numpy as np
import pytest

from nmkane_core import simulate
from web import curves as cv
from web import plots as pl
from web.panel import PlotPanel


@pytest.fixture(scope="module")
def knife_edge():
    return simulate({"system": "knife-edge", "t_final": 20})  # v = 1, ω = 0.5: a circle of radius 2


def curve_box(img: np.ndarray, rgb: tuple[int, int, int]) -> tuple[float, float]:
    """Width and height in pixels of the pixels of colour ``rgb`` (the drawn curve) in an RGBA image."""
    near = np.abs(img[..., :3].astype(int) - np.array(rgb)).sum(axis=2) < 60
    rows, cols = np.nonzero(near)
    return float(cols.max() - cols.min()), float(rows.max() - rows.min())


def test_knife_edge_circle_is_drawn_round_in_its_phase_portrait(knife_edge):
    phase = cv.quantity({"default": knife_edge}, "y", "x")
    assert isinstance(phase, cv.Phase)
    x, y = phase.xs[0], phase.ys[0]
    assert np.ptp(x) == pytest.approx(4.0, rel=1e-3) and np.ptp(y) == pytest.approx(4.0, rel=1e-3)
    img = cv.draw_phase(phase, t_now=20.0)  # the marker sits on the curve, inside its box
    w, h = curve_box(img, (0x1F, 0x77, 0xB4))
    assert w / h == pytest.approx(1.0, abs=0.04), f"the circle is drawn {w:.0f} × {h:.0f} px"
    assert phase.equal  # x and y place the blade: both lengths


def test_a_portrait_of_quantities_of_other_units_keeps_its_own_scales(knife_edge):
    assert not cv.quantity({"default": knife_edge}, "theta", "x").equal  # rad against m
    assert not cv.quantity({"default": knife_edge}, "u1", "x").equal  # m/s against m
    assert not cv.quantity({"default": knife_edge}, "2*y", "x").equal  # an expression: unit unknown
    assert cv.length_coordinates("knife-edge") == frozenset({"x", "y"})


@pytest.mark.parametrize("value", [0.0, -16.0, 3.5])
def test_a_constant_series_gets_a_small_axis_around_its_value(value):
    lo, hi = pl.constant_range([np.full(50, value), np.full(50, value)])
    assert lo < value < hi and (lo, hi) != (0.0, 100.0)
    assert hi - lo <= max(2.0, 0.2 * abs(value)) + 1e-12
    assert value - lo == pytest.approx(hi - value)  # symmetric: the line in the middle


def test_a_varying_series_keeps_the_automatic_range():
    assert pl.constant_range([np.linspace(0.0, 1e-3, 50)]) is None
    assert pl.constant_range([np.zeros(50), np.full(50, 1e-9)]) is None  # another run differs


class FakeGui:
    def __init__(self):
        self.plots: list[dict] = []

    def add_markdown(self, content):
        return SimpleNamespace(content=content)

    def add_uplot(self, **kw):
        self.plots.append(kw)
        return SimpleNamespace(**kw)

    def add_image(self, image, **kw):
        return SimpleNamespace(image=image, **kw)


class FakeView:
    kind = "knife-edge"
    plots = (("energy", "Energy drift ΔE(t)"), ("violation", "log₁₀ |φ|"), ("coord", "Plotted quantity"))

    def series_style(self, key, i, traj):
        return {}


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
    assert len(gui.plots) == 3
    for kw in gui.plots:  # uPlot's axis labels are 12 px, centred on their tick
        assert kw.get("padding") is not None and kw["padding"][0] >= 7, kw["title"]
