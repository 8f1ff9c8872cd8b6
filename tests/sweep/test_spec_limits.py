"""A sweep's size is counted from its text and refused before any value is made (issue 44):
NUM=10⁷ over a limit of 10⁴, or sixteen axes of 10⁷ each, fail at once; a seed is an integer
in [0, 2³² − 1]."""

import tracemalloc

import numpy as np
import pytest

from nmkane_core.errors import InputError
from nmkane_core.sweep.spec import MAX_POINTS, SEED_MAX, parse_axis, sweep_spec


def _refused(**kwargs) -> tuple[InputError, int]:
    """The error of ``sweep_spec(**kwargs)`` and the peak memory it allocated, bytes."""
    tracemalloc.start()
    try:
        with pytest.raises(InputError) as e:
            sweep_spec(**kwargs)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return e.value, peak


def test_a_ten_million_point_axis_over_the_limit_is_refused_without_making_a_value(made):
    err, peak = _refused(grid=["gamma1=0.001:0.002:10000000"], max_points=10_000)
    assert made == [] and peak < 1_000_000  # 10⁷ floats in a tuple and a set: ~900 MB
    assert err.field == "--grid" and err.value == "10,000,000 runs"
    assert err.allowed == "at most 10,000 runs per sweep" and "gamma1 10,000,000" in err.reason


def test_sixteen_axes_of_ten_million_each_are_counted_not_made(made):
    grid = [f"params.p{i}=0:1:10000000" for i in range(8)]
    log_grid = [f"initial.q{i}=1:2:10000000" for i in range(8)]
    err, peak = _refused(grid=grid, log_grid=log_grid)
    assert made == [] and peak < 1_000_000
    assert err.value == "about 10^112 runs" and err.allowed == f"at most {MAX_POINTS:,} runs per sweep"
    assert "… 8 more" in err.reason  # the reason lists the first axes, not all sixteen


def test_samples_times_grid_is_counted_before_the_grid_is_made(made):
    err, _ = _refused(grid=["gamma1=-2:-1:1000"], sample=["gamma2=-2:-1"], samples=1000, max_points=10_000)
    assert made == [] and err.value == "1,000,000 runs" and "gamma1 1,000 × samples 1,000" in err.reason


def test_parse_axis_refuses_more_values_than_max_points_before_making_them(made):
    with pytest.raises(InputError, match="at most 5 runs"):
        parse_axis("gamma1=0:1:10000000", max_points=5)
    assert made == []
    assert parse_axis("gamma1=0:1:5", max_points=5).values == (0.0, 0.25, 0.5, 0.75, 1.0)


def test_a_grid_at_the_limit_is_made_as_before():
    spec = sweep_spec(grid=["gamma1=-40:-10:4", "integrator=rk4,kutta-merson"], log_grid=["gamma2=-1:-100:3"])
    assert len(spec) == 24 and spec.axes[0].values == (-40.0, -30.0, -20.0, -10.0)
    assert np.allclose(spec.axes[2].values, [-1, -10, -100])
    assert len(sweep_spec(grid=["gamma1=0:1:12"], max_points=12)) == 12
    with pytest.raises(InputError, match="repeats"):  # duplicates are still found once made
        sweep_spec(grid=["every=1:2:5"])


@pytest.mark.parametrize("seed", [-1, SEED_MAX + 1, 2**64, True, 1.5, "3"])
def test_a_seed_outside_0_to_2_to_the_32_is_refused_naming_seed(seed):
    with pytest.raises(InputError) as e:
        sweep_spec(sample=["gamma2=-2:-1"], samples=2, seed=seed)
    assert e.value.field == "--seed" and e.value.allowed == "an integer in [0, 4294967295]"
    assert e.value.value == seed


@pytest.mark.parametrize("seed", [0, SEED_MAX, np.uint32(SEED_MAX), None])
def test_seeds_in_range_draw_the_sample(seed):
    spec = sweep_spec(sample=["gamma2=-2:-1"], samples=3, seed=seed)
    assert spec.sample_points().shape == (3, 1)
