"""The partition a run starts with is in its summary, the REST document and the CLI's report —
declared by the model, or picked by the library (issue 45, item 4: it was invisible)."""

import pytest

from nmkane_core import MechanicalModel, Parameter, System, plain_symbols, register, simulate
from nmkane_core.run.registry import unregister

NAME = "test-knife-edge-undeclared"


def _knife_edge() -> MechanicalModel:
    import sympy as sp

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m = sp.Symbol("m", real=True)
    return MechanicalModel(
        name="undeclared",
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m,),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, m / 2),
        P=sp.zeros(3, 1),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},  # no u_independent: the library picks
        energy=m * (u1**2 + u2**2) / 2 + m * u3**2 / 4,
    )


@pytest.fixture(scope="module")
def system():
    registered = register(
        System(
            name=NAME,
            title="Knife edge, no declared partition (test)",
            variants=_knife_edge,
            parameters={"m": Parameter(1.0, 0.0, 10.0, "kg")},
            default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u2": 0.0, "u3": 1.0},
            default_dt=0.01,
            default_t_final=1.0,
        )
    )
    yield registered
    unregister(NAME)


def test_a_picked_partition_is_reported_with_how_it_was_chosen(system, capsys):
    run = simulate({"system": system.name}, progress=False)
    part = run.summary["partition"]
    assert part["chosen"] == "pivoting" and part["q_dependent"] == []
    # at θ = 0 the constraint is u2 = 0: u2 is the dependent speed
    assert part["u_independent"] == ["u1", "u3"]
    from nmkane_core.cli import main

    assert main(["run", system.name, "--no-progress"]) == 0
    assert "partition u_I: u1, u3 (picked by pivoting at the default state)" in capsys.readouterr().out


def test_a_declared_partition_is_reported_as_declared():
    part = simulate({"system": "appell-hamel", "t_final": 0.1}, progress=False).summary["partition"]
    assert part == {"u_independent": ["u1", "u2"], "q_dependent": ["z"], "chosen": "declared"}


def test_nmkane_matrices_says_why_the_partition_is_what_it_is(system, capsys):
    """The pivots of the elimination that picked it (the speed, the constraint, |pivot|) and J2's
    estimate at the default state; a declared one is said to be declared."""
    from nmkane_core.cli import main

    assert main(["matrices", system.name, "--matrix", "J2"]) == 0
    out = capsys.readouterr().out
    assert "partition: u_I = (u1, u3), picked by pivoting at the default state" in out
    assert "u2 from no_side_slip: 1" in out  # at θ = 0 the row is [0, 1, 0]: u2 is its only pivot
    assert "J2 estimate at the default state: 1" in out
    assert main(["matrices", "appell-hamel", "--matrix", "J2"]) == 0
    out = capsys.readouterr().out
    assert "partition: u_I = (u1, u2), declared by the model" in out and "q solved from ψ = 0: z (declared)" in out
