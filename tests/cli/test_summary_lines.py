"""The terminal summary of ``nmkane run`` stays readable for a large model: a line of per-constraint
values shows the largest ones and how many more (IFToMM A02 at N = 40 printed 80 of each)."""

from types import SimpleNamespace

import numpy as np

from nmkane_core.cli.run_cmd import MOST, format_summary


def _run(n_constraints: int, n_state: int):
    viol = {f"close{i}": 10.0 ** -(i % 7 + 10) for i in range(n_constraints)}
    summary = {
        "status": "ok",
        "message": "completed",
        "steps": 10,
        "rhs_evals": 50,
        "wall_time_s": 0.01,
        "max_abs_energy_drift": 1e-10,
        "final_energy_drift": 1e-11,
        "max_abs_violation": viol,
        "max_abs_multiplier": {k: 1.0 + i for i, k in enumerate(viol)},
    }
    settings = {"model": "default", "integrator": "kutta-merson", "dt": 0.001, "t_final": 0.01}
    state = {f"q{i}": np.array([0.0, float(i)]) for i in range(n_state)}
    return SimpleNamespace(system="chain", summary=summary, settings=settings, state=state, t=np.array([0.0, 0.01]))


def test_a_large_models_lines_show_the_largest_values_and_count_the_rest():
    lines = {ln[:8]: ln for ln in format_summary(_run(80, 162)).splitlines()}
    phi, lam, final = lines["max |φ| "], lines["max |λ| "], lines["final   "]
    assert phi.count("e-") == MOST and "(72 more, each smaller)" in phi
    assert phi.count("1.000e-10") == MOST and phi.split("  ", 1)[1].startswith(
        "close0 "
    )  # the largest (i % 7 == 0) first
    assert "close79 8.000e+01" in lam and "(72 more, each smaller)" in lam
    assert final.count(" = ") == 2 * MOST + 1 and "(162 values; --out FILE.json has them all)" in final


def test_a_small_models_lines_show_every_value_in_order():
    lines = {ln[:8]: ln for ln in format_summary(_run(3, 10)).splitlines()}
    assert [p.split()[0] for p in lines["max |φ| "].split("  ", 1)[1].split(", ")] == ["close0", "close1", "close2"]
    assert lines["final   "].count(" = ") == 11 and "values;" not in lines["final   "]
