"""Readable plots (the teacher's item 5): a typed quantity against time or against another
one (a phase portrait), parsed on a whitelist and never evaluated as code; axis titles with
units; the legend names each run's line style; a long run is shown in pages, not as a band;
the marker waits while the viewer points at or zooms a plot."""

import numpy as np
import pytest

from nmkane_core.analysis import expressions as ex
from web.panel import WINDOW_S
from web.session import MechanismApp

NAMES = ("t", "theta", "u1", "x", "E", "dE")


@pytest.mark.parametrize(
    "text,value",
    [
        ("u1*cos(theta)", 2.0 * np.cos(0.5)),
        ("x^2 + 1", 10.0),
        ("-dE/E", 0.25),
        ("sqrt(abs(x)) - pi", np.sqrt(3.0) - np.pi),
    ],
)
def test_quantities_are_read_from_the_whitelist(text, value):
    vals = {"t": np.zeros(1), "theta": np.full(1, 0.5), "u1": np.full(1, 2.0), "x": np.full(1, 3.0)}
    vals |= {"E": np.full(1, 4.0), "dE": np.full(1, -1.0)}
    assert ex.evaluate(ex.parse(text, NAMES), vals)[0] == pytest.approx(value)


@pytest.mark.parametrize(
    "text,why",
    [
        ("__import__('os').system('true')", "only these functions"),
        ("theta.real", "attribute is not allowed"),
        ("x[0]", "subscript is not allowed"),
        ("(lambda: 1)()", "only these functions"),
        ("'abc'", "constant is not allowed"),
        ("omega", "unknown name 'omega'"),
        ("open('f')", "only these functions"),
        ("x if x else u1", "ifexp is not allowed"),
        ("", "empty"),
        ("u1 +", "is not an expression"),
    ],
)
def test_anything_else_is_refused_with_the_reason(text, why):
    with pytest.raises(ex.ExpressionError, match=why):
        ex.parse(text, NAMES)


def test_arithmetic_edge_cases_give_numbers_not_exceptions():
    vals = {"x": np.array([0.0, 1.0])}
    out = ex.evaluate(ex.parse("1/x + 2^99999", ("x",)), vals)
    assert np.isinf(out).all()


@pytest.fixture()
def app(module_server):
    a = MechanismApp(module_server, sync=True)
    yield a
    a.close()


def test_a_typed_quantity_is_plotted_against_time_with_axis_titles(app):
    app.control("option.plot").text.value = "u1*cos(theta)"
    run = app.traj.main
    h = app.plot_handles[("appell-hamel", "coord")]
    y = h.data[1]  # (decimated keeping each bucket's extremes)
    want = run.state["u1"] * np.cos(run.state["theta"])
    assert y.min() == pytest.approx(want.min()) and y.max() == pytest.approx(want.max())
    assert h.axes[0]["label"] == "t [s]" and h.axes[1]["label"] == "u1*cos(theta)"
    energy = app.plot_handles[("appell-hamel", "energy")]
    assert energy.axes[1]["label"].startswith("ΔE = E − E(0) [") and energy.axes[1]["size"] >= 60
    assert app.link.pairs()[-1] == ("plot", "u1*cos(theta)")
    app.control("option.plot").text.value = "theta.real"  # refused beside the box; the plot keeps its quantity
    box = app.control("option.plot")
    assert box.value == "u1*cos(theta)" and box.message.visible and "attribute" in box.message.content


def test_against_another_quantity_the_plot_is_a_phase_portrait(app):
    app.control("option.plot").text.value = "u1"
    app.control("option.plot_x").text.value = "theta"
    assert "phase" in app.traj.plots and "coord" not in app.traj.plots
    chart = app.plots.phases["appell-hamel"]  # a uPlot of its own
    assert chart.visible and not app.plot_handles[("appell-hamel", "coord")].visible
    run = app.traj.main
    x, y = chart.data[0], chart.data[1]
    assert x.min() == pytest.approx(run.state["theta"].min()) and y.max() == pytest.approx(run.state["u1"].max())
    xr, yr = chart.scales["x"]["range"], chart.scales["y"]["range"]
    assert xr[0] < x.min() and x.max() < xr[1] and yr[0] < y.min() and y.max() < yr[1]  # every point inside
    assert chart.axes[0]["label"] == "theta" and chart.axes[1]["label"] == "u1"
    app.control("option.plot_x").text.value = "t"
    assert not chart.visible and app.plot_handles[("appell-hamel", "coord")].visible


def test_ghost_runs_are_named_with_their_line_style_in_the_legend(app):
    app.control("option.compare").value = "linear"
    labels = [s["label"] for s in app.plot_handles[("appell-hamel", "energy")].series[1:]]
    assert labels == ["ΔE — nonlinear", "ΔE — linear, dashed"]
    assert "orange**, dashed: linear (ghost)" in app.legends["appell-hamel"].content


def test_a_long_run_is_shown_in_pages_that_follow_the_time(app):
    app.scene_choice.value = next(t for t, n in app.choices.items() if n == "sliding-particle")  # 300 s
    h = app.plot_handles[("sliding-particle", "coord")]
    assert tuple(h.scales["x"]["range"]) == (0.0, WINDOW_S)
    assert h.data[0][-1] <= WINDOW_S + 1 and len(h.data[0]) > 100  # the page's rows, not the whole run's
    app.seek(100.0)
    assert tuple(h.scales["x"]["range"]) == (90.0, 120.0) and h.data[0][0] >= 89.0
    app.plots.busy = True  # the viewer points at a plot: the marker and the page wait
    app.seek(200.0)
    assert tuple(h.scales["x"]["range"]) == (90.0, 120.0)
    app._on_page({"kind": "plots", "busy": False})
    assert tuple(h.scales["x"]["range"]) == (180.0, 210.0) and h.axes[2]["splits"] == (200.0,)
