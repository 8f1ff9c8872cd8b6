"""Plots as the page draws them (issue 43, item 5), read from the uPlot charts themselves
(viser's client registers each in ``window.__viserTestpoints.uplots`` by its id): a phase
portrait of two lengths has as many metres per pixel across as up; a series identically zero
gets a finite axis with finite ticks; every tick value lies inside its chart's canvas, in its
axis' own strip (not over the axis' title, not cut at the canvas' edge).

Before: the phase portrait was a matplotlib image (no chart to read); a quantity of long numbers
(1e6·x: "2,000,000") had tick values wider than the 54 px its axis gives them, cut at the
canvas' left edge."""

import math

import pytest

from tests._helpers import require_browser
from tests.web._pages import until

require_browser()

from web import plots as pl
from web import viser_compat as compat
from web.app import launch
from web.chromium import POLL_MS
from web.screenshot import open_page

pytestmark = pytest.mark.browser

SYSTEM = "knife-edge"  # x, y: the blade's place (two lengths: a circle of radius 2); ΔE ≡ 0

#: ``page.evaluate(CHART, uuid)``: the drawn chart of a uPlot handle — its scales, plot box
#: (canvas pixels), canvas size, and per shown axis each tick value's box (canvas pixels) with
#: the axis' own strip; null until the chart exists
CHART = """(uuid) => {
  const tp = ((window.__viserTestpoints || {}).uplots || {})[uuid];
  if (!tp) return null;
  const u = tp.chart, r = devicePixelRatio;
  const ctx = document.createElement('canvas').getContext('2d');
  const axes = [];
  u.axes.forEach((a, i) => {
    if (!a.show || !a._show || a.label == null || !a._values) return;
    ctx.font = a.font[0];
    const size = a.font[1], ori = a.side % 2, tick = (a.ticks && a.ticks.show ? a.ticks.size : 0);
    const values = [];
    a._values.forEach((text, j) => {
      if (text == null || text === '') return;
      const w = ctx.measureText(String(text)).width, p = u.valToPos(a._splits[j], a.scale, true);
      let box;
      if (a.side === 3) {  // left: right-aligned, its right end tick + gap left of the plot
        const right = (a._pos - tick - a.gap) * r;
        box = [right - w, p - size / 2, right, p + size / 2];
      } else if (a.side === 2) {  // bottom: centred under its tick
        const top = (a._pos + tick + a.gap) * r;
        box = [p - w / 2, top, p + w / 2, top + size];
      } else return;
      values.push({text: String(text), box: box});
    });
    const strip = a.side === 3 ? [(a._pos - a._size) * r, a._pos * r] : [a._pos * r, (a._pos + a._size) * r];
    axes.push({side: a.side, strip: strip, values: values});
  });
  const sc = (k) => (u.scales[k] ? [u.scales[k].min, u.scales[k].max] : null);
  return {x: sc('x'), y: sc('y'), bbox: u.bbox, canvas: [u.ctx.canvas.width, u.ctx.canvas.height], axes: axes};
}"""


@pytest.fixture(scope="module")
def app():
    handle = launch(port=0, scene=SYSTEM)
    yield handle
    handle.stop()


@pytest.fixture(scope="module")
def page_session(app, browser_module):
    page = open_page(browser_module, app.url + "?hideViserLogo", width=1400, height=900)
    session = app.wait_for_session()
    assert session.wait_idle(120) and session.traj.kind == SYSTEM
    session.set_playing(False)
    yield page, session
    page.close()


@pytest.fixture(scope="module")
def browser_module(_chromium):
    """The shared Chromium with the tests' frame cap, for this module's one page."""
    from tests.web.conftest import _FrameCapped

    return _FrameCapped(_chromium)


def chart(page, handle, ready: str = "true", timeout_ms: int = 60000) -> dict:
    """The drawn chart of ``handle`` once it has its size (a chart made visible is mounted at
    width 0, then sized) and ``ready`` (a JS condition on ``c``, the chart's reading) holds."""
    uuid = compat.gui_uuid(handle)
    page.wait_for_function(
        f"(uuid) => {{ const c = ({CHART})(uuid); return !!c && c.bbox.width > 0 && c.bbox.height > 0 && ({ready}); }}",
        arg=uuid,
        timeout=timeout_ms,
        polling=POLL_MS,
    )
    return page.evaluate(CHART, uuid)


def _near(js: str, value: float) -> str:
    """A JS condition: the expression ``js`` equals ``value`` (to round-off)."""
    return f"Math.abs(({js}) - ({value!r})) <= 1e-9 * (1 + Math.abs({value!r}))"


def ticks_inside(c: dict, what: str) -> None:
    """Every tick value of the chart inside the canvas and inside its axis' strip."""
    width, height = c["canvas"]
    assert c["axes"], f"{what}: no axis drawn"
    for axis in c["axes"]:
        lo, hi = axis["strip"]
        for v in axis["values"]:
            x0, y0, x1, y1 = v["box"]
            where = f"{what}: tick value {v['text']!r} at {[round(b, 1) for b in v['box']]}"
            assert x0 >= -0.5 and x1 <= width + 0.5 and y0 >= -0.5 and y1 <= height + 0.5, f"{where} leaves the canvas"
            if axis["side"] == 3:
                assert x0 >= lo - 0.5, f"{where} runs over the axis' title (its strip starts at {lo:.1f})"
            else:
                assert y1 <= hi + 0.5, f"{where} runs over the axis' title (its strip ends at {hi:.1f})"


def test_a_phase_portrait_of_two_lengths_has_equal_scales_in_the_drawn_chart(page_session):
    page, session = page_session
    session.control("option.plot").value = "y"
    session.control("option.plot_x").value = "x"
    assert session.wait_idle(60)
    until(lambda: "phase" in session.traj.plots, 30, "the phase portrait")
    handle = session.plots.phases[SYSTEM]
    assert handle.visible
    xr, yr = handle.scales["x"]["range"], handle.scales["y"]["range"]
    c = chart(page, handle, ready=f"c.x && c.y && {_near('c.x[0]', xr[0])} && {_near('c.y[1]', yr[1])}")
    per_x = (c["x"][1] - c["x"][0]) / c["bbox"]["width"]
    per_y = (c["y"][1] - c["y"][0]) / c["bbox"]["height"]
    assert per_x == pytest.approx(per_y, rel=0.02), f"{per_x:.5f} m/px across, {per_y:.5f} m/px up"
    print(f"phase portrait: {per_x:.5f} m/px across, {per_y:.5f} m/px up ({abs(per_x / per_y - 1):.2%} apart)")
    phase = session.traj.plots["phase"]
    (x_lo, x_hi), (y_lo, y_hi) = phase.box()
    assert c["x"][0] < x_lo and x_hi < c["x"][1] and c["y"][0] < y_lo and y_hi < c["y"][1]  # the whole circle
    assert session.plots.width == pytest.approx(page.evaluate("() => document.querySelector('.uplot').offsetWidth"))
    ticks_inside(c, "phase portrait")


def test_a_series_identically_zero_gets_a_finite_axis_with_finite_ticks(page_session):
    page, session = page_session
    energy = session.plot_handles[(SYSTEM, "energy")]  # the blade's force does no work: ΔE ≡ 0
    c = chart(page, energy, ready="c.y && c.axes.length > 1")
    lo, hi = c["y"]
    assert math.isfinite(lo) and math.isfinite(hi) and lo < 0.0 < hi and hi - lo <= 2.0 + 1e-9
    values = [v["text"] for axis in c["axes"] if axis["side"] == 3 for v in axis["values"]]
    assert values and all(math.isfinite(float(t.replace(",", ""))) for t in values), values
    violation = chart(page, session.plot_handles[(SYSTEM, "violation")], ready="c.y && c.axes.length > 1")
    assert all(math.isfinite(v) for v in violation["y"]) and violation["y"][0] < -16 < violation["y"][1]
    ticks_inside(c, "energy drift")
    ticks_inside(violation, "violation")


@pytest.mark.parametrize("quantity", ["1e6*x", "-1234.5*y", "1e-12*x"])
def test_the_tick_values_of_long_numbers_stay_inside_the_canvas(page_session, quantity):
    page, session = page_session
    session.control("option.plot_x").value = "t"
    session.control("option.plot").value = quantity
    assert session.wait_idle(60)
    until(lambda: "coord" in session.traj.plots and quantity in session.traj.plots["coord"].y_label, 30, quantity)
    handle = session.plot_handles[(SYSTEM, "coord")]
    label = session.traj.plots["coord"].y_label
    size = handle.axes[1]["size"]
    uuid = compat.gui_uuid(handle)
    # the chart as the page has it (none for a moment while the page makes it again)
    drawn = lambda: page.evaluate(  # noqa: E731
        "(uuid) => window.__viserTestpoints.uplots[uuid]?.chart?.axes?.[1]?.label ?? null", uuid
    )
    # the page draws the new axes when it has them (the previous quantity's chart also passes the
    # check below: reading it first failed now and then with the old label, 'x')
    until(lambda: drawn() == label, 30, f"the page to draw the axis title {label!r}")
    c = chart(page, handle, ready="c.axes.length > 1 && c.axes.some((a) => a.side === 3 && a.values.length > 1)")
    assert size >= pl.Y_AXIS_PX
    ticks_inside(c, f"{quantity} against t")
