"""The bicycle's tyre forces against an independent route: sympy's KanesMethod on the same
bodies and loads with the multiplier system solved numerically
(:func:`nmkane_core.systems.whipple_bicycle_oracle.bicycle_sympy_forces`), at random states.

* F_c = Q u̇ − P of the run equals the oracle's M u̇ − F;
* the declared tyre forces, as forces at the wheels' material contact points, make exactly
  that generalized force (Σ (∂v/∂u)ᵀ R = F_c) — friction and the front normal force;
* Newton on the whole bicycle, Σ m a_G = weight + R_rear + R_front, holds with the oracle's
  accelerations — the rear normal force, the one F_c cannot see.
"""

import numpy as np
import pytest

from nmkane_core import accelerations, get_system, simulate
from nmkane_core.kernel.forces import compile_forces
from nmkane_core.run.plan import resolve

FLIP = np.diag([1.0, -1.0, -1.0])  # the visuals' world (z up) ↔ Moore's N (z down)


@pytest.fixture(scope="module")
def oracle():
    from nmkane_core.systems.whipple_bicycle_oracle import bicycle_sympy_forces

    return bicycle_sympy_forces()


def _states(count, seed=5):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        init = {
            "q3": rng.uniform(-3, 3),
            "q4": rng.uniform(-0.4, 0.4),
            "q7": rng.uniform(-0.5, 0.5),
            "u4": rng.uniform(-1.5, 1.5),
            "u6": rng.uniform(-30, -3),
            "u7": rng.uniform(-1.5, 1.5),
        }
        plan = resolve({"system": "whipple-bicycle", "initial": init})
        yield plan, dict(zip(plan.info.state_names, plan.x0, strict=True))


def test_tyre_forces_match_kanes_method_oracle_at_random_states(oracle):
    system = get_system("whipple-bicycle")
    compiled = compile_forces(system)
    for plan, state in _states(8):
        acc = accelerations(system, state)
        o = oracle(plan.x0)
        fc = np.array([acc.constraint_forces[k] for k in plan.info.u])
        scale = np.max(np.abs(o["Fc"]))
        assert np.max(np.abs(fc - o["Fc"])) < 1e-9 * scale
        geo = compiled.geometry({k: np.array([v]) for k, v in state.items()}, plan.params)
        R = {}
        for f in compiled.forces:
            axes = geo[f["name"]][1][0]
            R[f["name"]] = FLIP @ (axes @ np.array([acc.point_forces[c] for c in f["columns"]]))
        generalized = o["Jr"].T @ R["rear_tyre"] + o["Jf"].T @ R["front_tyre"]
        assert np.max(np.abs(generalized - o["Fc"])) < 1e-9 * scale
        newton = R["rear_tyre"] + R["front_tyre"] + o["weight"] - o["momentum_rate"]
        assert np.max(np.abs(newton)) < 1e-9 * np.max(np.abs(o["weight"]))


def test_upright_bicycle_rolling_straight_shares_its_weight_by_the_mass_centre():
    """Straight upright running at constant speed: no friction, the normal forces carry the
    weight in the lever ratio of the total mass centre (x from the rear contact, wheelbase w)."""
    plan = resolve({"system": "whipple-bicycle"})  # upright, straight, 5 m/s
    acc = accelerations("whipple-bicycle", dict(zip(plan.info.state_names, plan.x0, strict=True)))
    masses = {"mR": (2.0, 0.0), "mB": (85.0, 0.3), "mH": (4.0, 0.9), "mF": (3.0, 1.02)}
    total = sum(m for m, _ in masses.values())
    x_cm = sum(m * x for m, x in masses.values()) / total
    front = total * 9.81 * x_cm / 1.02
    pf = acc.point_forces
    assert pf["front_tyre.normal"] == pytest.approx(front, rel=1e-10)
    assert pf["rear_tyre.normal"] == pytest.approx(total * 9.81 - front, rel=1e-10)
    for k in ("rear_tyre.longitudinal", "rear_tyre.lateral", "front_tyre.longitudinal", "front_tyre.lateral"):
        assert abs(pf[k]) < 1e-9


def test_a_fall_cuts_the_tyre_forces_with_the_state():
    run = simulate({"system": "whipple-bicycle", "initial": {"u6": -10.0, "u4": 0.5}, "t_final": 5.0, "every": 10})
    assert run.status == "event"
    assert all(v.shape == run.t.shape for v in run.point_forces.values())
    normal = run.point_forces["rear_tyre.normal"]
    assert run.summary["max_abs_point_force"]["rear_tyre"] >= np.max(np.abs(normal))
