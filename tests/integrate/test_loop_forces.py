"""The compiled loops' constraint forces: each output row's F_c and λ are those of one
right-hand-side evaluation at that row's state (the kernel's ``forces_rows``, which the
scipy adapter and ``accelerations()`` use), whatever the recording stride, the integrator
or the solve.  The loops take them from the first stage of the step that starts at the row
and compute them after the step's later stages (which overwrite Q and P in the work array)."""

import numpy as np
import pytest

from nmkane_core import simulate
from nmkane_core.run.plan import resolve
from nmkane_core.run.simulate import kernel_for

CASES = [
    ({"system": "appell-hamel", "model": "nonlinear", "t_final": 2.0, "dt": 0.01, "every": 1}, True),
    ({"system": "appell-hamel", "model": "linear", "t_final": 2.0, "dt": 0.01, "every": 7}, True),
    ({"system": "sliding-particle", "t_final": 3.0, "dt": 0.01, "every": 3, "gamma1": -5.0, "gamma2": -10.0}, True),
    ({"system": "appell-hamel", "integrator": "kutta-merson-adaptive", "t_final": 2.0, "rtol": 1e-8}, True),
    ({"system": "iftomm-a02", "t_final": 2.0, "dt": 0.002, "every": 5}, False),
    ({"system": "iftomm-a02", "t_final": 2.0, "dt": 0.002, "every": 5, "solve": "robust"}, False),
]


@pytest.mark.parametrize(
    ("settings", "same_multipliers"), CASES, ids=lambda c: "-".join(map(str, c.values())) if isinstance(c, dict) else ""
)
def test_each_rows_forces_are_those_of_one_evaluation_at_its_state(settings, same_multipliers):
    plan = resolve(settings)
    run = simulate(plan, progress=False)
    assert run.summary["status"] == "ok", run.summary["message"]
    info = plan.info
    mod = kernel_for(plan.system, plan.variant)
    X = np.column_stack([run.state[k] for k in info.state_names])
    F = np.empty((len(run.t), len(info.u)))
    L = np.empty((len(run.t), len(info.constraint_names)))
    mod.forces_rows(run.t, X, plan.p, plan.G, plan.G1, plan.G2, F, L)
    rows_F = np.column_stack([run.constraint_forces[k] for k in info.u])
    scale = max(1.0, float(np.abs(F).max()))
    assert len(run.t) > 20
    assert np.abs(rows_F - F).max() <= 1e-9 * scale
    if same_multipliers:  # the declared partition throughout: the same J2ᵀλ = (F_c)_D
        rows_L = np.column_stack([run.multipliers[k] for k in info.constraint_names])
        assert np.abs(rows_L - L).max() <= 1e-9 * max(1.0, float(np.abs(L).max()))
