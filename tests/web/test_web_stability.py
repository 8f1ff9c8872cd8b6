"""web/stability.py without a browser: the plot's data never holds NaN (uPlot drops a curve
with one), every eigenvalue is a point, and the marker follows the run's speed."""

import numpy as np

from nmkane_core import get_system
from web.stability import StabilityPlot


def test_plot_data_has_every_eigenvalue_and_no_nan():
    rows = [
        {"value": 1.0, "eigenvalues": [[-5.0, 0.0], [1.0, 2.0], [1.0, -2.0], [-30.0, 0.0]]},
        {"value": 2.0, "eigenvalues": [[-4.0, 0.0], [0.5, 3.0], [0.5, -3.0], [-31.0, 0.0]]},
    ]
    x, *re, im = StabilityPlot.data(rows)
    assert list(x) == [1.0, 2.0] and len(re) == 4
    assert all(np.all(np.isfinite(r)) for r in re) and np.all(np.isfinite(im))
    assert re[0][0] == -12.0 and re[3][0] == 1.0  # sorted, clipped just outside ±10
    assert list(im) == [2.0, 3.0]


def test_bicycle_declares_a_speed_sweep_with_the_benchmark_references():
    st = get_system("whipple-bicycle").stability
    params = get_system("whipple-bicycle").resolve_params({})
    assert st.over == "speed" and st.keep == ("q4", "q7", "u4", "u7")
    assert st.value_of({"u6": -10.0}, params) == 3.0
    assert st.state(3.0, params) == {"u6": -10.0}
    assert set(st.reference) == {"weave", "capsize"}
