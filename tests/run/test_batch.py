"""Batches of runs (Γ sweeps) over the machine's cores give the same results as one by one."""

import numpy as np

from nmkane_core.run.simulate import simulate, simulate_many


def test_gamma_sweep_in_parallel_equals_sequential_runs():
    sweep = [
        {"system": "sliding-particle", "gamma1": g, "gamma2": -((g / 2) ** 2), "dt": 0.002, "t_final": 20, "every": 50}
        for g in (-40.0, -20.0, -10.0, -5.0)
    ]
    par = simulate_many(sweep, workers=2, progress=False)
    for s, r in zip(sweep, par, strict=True):
        one = simulate(s, progress=False)
        assert r.settings["gamma1"] == s["gamma1"]
        np.testing.assert_array_equal(r.state["x"], one.state["x"])
        assert r.summary["max_abs_violation"] == one.summary["max_abs_violation"]


def test_output_memory_follows_rows_not_steps():
    run = simulate({"system": "appell-hamel", "dt": 0.001, "t_final": 100, "every": 10000})
    assert run.summary["steps"] == 100_000 and len(run.t) == 11
