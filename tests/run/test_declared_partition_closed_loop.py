"""A closed loop declared as the paper's procedure does — u_independent and q_dependent given,
nothing said about singular positions — runs like one declared without a partition (issue 42):
the declared partition is the preferred one, used where its J2 is well-conditioned, with the
re-partitioning and the rank-robust solve elsewhere (``solve="auto"``, every model's default);
``solve="paper"`` stays available, and a run whose motion blows up stops at the run's energy
bound (``drifted``), not 50 orders of magnitude later.

The model is IFToMM A02 with N = 2 (the catalogue's equations) declared through the public API
as a user would: its own System, the library's default settings (no projection, Γ = 0)."""

import dataclasses
import math

import numpy as np
import pytest

from nmkane_core import System, register, simulate
from nmkane_core.systems import iftomm_a02

NAME = "declared-four-bar"


@pytest.fixture(scope="module")
def system():
    md = dataclasses.replace(iftomm_a02.model(2), singular_positions=False, name="declared")
    assert md.u_independent and md.q_dependent and md.m == 4  # a declared, non-redundant partition
    sys_ = System(
        name=NAME,
        title="the N-four-bar, partition declared",
        variants=lambda: md,
        parameters=iftomm_a02.PARAMETERS,
        default_initial=iftomm_a02.initial_state(2),
        default_dt=1e-3,
        default_t_final=10.0,
    )
    register(sys_)
    return sys_


def _errors(run) -> dict[str, float]:
    qn, un = iftomm_a02.names(2)
    x = np.column_stack([run.state[k] for k in (*qn, *un)])
    return iftomm_a02.acceptance(run.t, x, 2, energy=run.energy)


@pytest.mark.parametrize(
    "settings, velocity",
    [
        ({}, 1e-8),  # measured 1.4e-10
        ({"integrator": "kutta-merson-adaptive"}, 1e-6),  # 1.3e-7
        # 4.1e-10; without the projection of the steps near the passages 1.4e-6 (a velocity kick
        # at the second passage, t = 1.229 s, that the Baumgarte terms damp within a few steps)
        ({"gamma1": -20.0, "gamma2": -100.0}, 1e-8),
        ({"gamma1": 0.0, "gamma2": -100.0}, 1e-8),  # 5.7e-10; without: it leaves the branch, drifted
    ],
)
def test_declared_partition_runs_through_the_singular_positions(system, settings, velocity):
    """Ten horizontal passages in 10 s, on the exact parallelogram motion.  Before: the kernel
    had the paper's solve only, and the runs ended diverged at t = 3.3–7.4 s (|ΔE| up to 1e96 J)
    or singular."""
    run = simulate({"system": NAME, **settings}, progress=False)
    assert run.status == "ok", run.summary["message"]
    assert run.settings["solve"] == "auto"
    assert run.summary["robust_solve"]["near_singular_projections"] >= 20  # 50 (adaptive: 26)
    assert run.t[-1] == pytest.approx(10.0)
    err = _errors(run)
    assert err["B0_position"] < 1e-6 and err["B0_velocity"] < velocity and err["energy_drift"] < 1e-6, err


def test_the_paper_solve_on_the_declared_partition_stops_at_the_energy_bound(system):
    """The paper's solve with the declared partition, unequilibrated, amplifies the round-off at
    the singular positions until the motion blows up (t ≈ 7.4 s): the run stops at the first state
    past 10⁶ × the initial energy scale, with the bound in its summary."""
    run = simulate({"system": NAME, "solve": "paper"}, progress=False)
    s = run.summary
    assert run.status == "drifted" and "past the run's bound" in s["message"], s["message"]
    assert s["robust_solve"] is None  # the paper's own path
    E0 = float(run.energy[0])
    assert s["bounds"] == {"energy_drift": pytest.approx(1e6 * abs(E0)), "violation": None}
    assert math.isfinite(s["max_abs_energy_drift"]) and s["max_abs_energy_drift"] < 1e30
    assert np.abs(run.energy - E0).max() <= s["bounds"]["energy_drift"]  # the kept rows are within it


def test_a_violation_bound_stops_the_run_where_the_constraints_are_left(system):
    """Γ1 = 0 and no projection at all (not even near the passages) leave the round-off kicks of
    the passages undamped: with a violation bound the run stops where |ψ| first exceeds it, long
    before the energy bound."""
    off = {"gamma1": 0.0, "gamma2": -100.0, "singular_projection": False}
    run = simulate({"system": NAME, **off, "max_violation": 1e-6}, progress=False)
    s = run.summary
    assert run.status == "drifted" and "violation of close" in s["message"], s["message"]
    assert s["bounds"]["violation"] == 1e-6
    assert max(np.abs(v).max() for v in run.violation.values()) <= 1e-6
    free = simulate({"system": NAME, **off}, progress=False)
    assert free.status == "drifted" and free.t[-1] > run.t[-1]  # the energy bound, later


def test_the_papers_examples_keep_the_papers_solve():
    for name in ("appell-hamel", "sliding-particle"):
        run = simulate({"system": name, "t_final": 1.0}, progress=False)
        assert run.settings["solve"] == "paper" and run.summary["robust_solve"] is None
        auto = simulate({"system": name, "t_final": 1.0, "solve": "auto"}, progress=False)
        assert auto.status == "ok" and auto.summary["robust_solve"] is not None
        for k in run.state:  # the same motion either way, to round-off
            assert np.allclose(run.state[k], auto.state[k], rtol=1e-9, atol=1e-9), k


@pytest.fixture(scope="module")
def parallelogram():
    """Three parallel cranks and one coupler pinned to all three tips: all four closure
    equations (rank 3) with u_I = (dth0,) declared — a user's over-constrained loop."""
    from nmkane_core import Parameter
    from nmkane_core.systems import iftomm_a04

    md = iftomm_a04.parallelogram_model(redundant=True)
    assert md.m == 4 and len(md.u_independent) == 1
    params = {"L": Parameter(1.0, 0.1, 10.0, "m", "rod"), "m": Parameter(1.0, 0.1, 10.0, "kg", "rod"),
              "g": Parameter(9.81, 0.0, 20.0, "m/s²", "gravity")}  # fmt: skip
    register(
        System(
            name="declared-parallelogram",
            variants=lambda: md,
            parameters=params,
            default_initial=iftomm_a04.parallelogram_state(),
            default_dt=1e-3,
            default_t_final=10.0,
        )
    )
    return "declared-parallelogram"


@pytest.mark.parametrize("settings", [{}, {"gamma1": -20.0, "gamma2": -100.0}, {"integrator": "kutta-merson-adaptive"}])
def test_a_declared_redundant_parallelogram_runs_on_its_exact_motion(parallelogram, settings):
    """Its redundant equations disagree as soon as the state drifts (by 1e-6, relative, near the
    horizontal position: the run used to end singular, inconsistent, at 2.6 s); a model whose
    equations are redundant gets the mass-metric projection by default (System default_projection
    "auto").  Measured: B0 within 1.5e-11 (adaptive 1.9e-8), |ΔE| 2.4e-11 (6.5e-9)."""
    from nmkane_core.systems import iftomm_a02

    run = simulate({"system": parallelogram, **settings}, progress=False)
    assert run.status == "ok", run.summary["message"]
    assert run.settings["projection"] == "yoon" and run.t[-1] == pytest.approx(10.0)
    x = np.column_stack([run.state[k] for k in ("th0", "dth0")])
    th, w = iftomm_a02.exact_motion(run.t, 2, x[0, 0], x[0, 1])
    assert np.abs(np.cos(x[:, 0]) - np.cos(th)).max() < 1e-6 and np.abs(x[:, 1] - w).max() < 1e-6
    assert run.summary["max_abs_energy_drift"] < 1e-6
    off = {"projection": "none", "singular_projection": False}
    unprojected = simulate({"system": parallelogram, **settings, **off}, progress=False)
    assert unprojected.status == "singular" and "inconsistent" in unprojected.summary["message"]
