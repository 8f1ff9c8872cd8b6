"""A `MechanicalModel` refuses, when it is constructed, what its generated code could not
evaluate (issue 44, item 9): symbols given twice (q = (x, x), a speed that is also a
coordinate, a parameter named like a state value or t) and any symbol of an expression that is
not a coordinate, a speed, t or a declared parameter — an unknown `k` in P or in the energy
used to pass and end the first run with a NameError from the generated code."""

from __future__ import annotations

import pytest
import sympy as sp

from nmkane_core import InputError, MechanicalModel, plain_symbols

x, y = plain_symbols("x y")
u1, u2 = plain_symbols("u1 u2")
m, g, k = sp.symbols("m g k", positive=True)


def particle(**changes) -> MechanicalModel:
    """A particle in a plane under gravity, with the given fields replaced."""
    fields = dict(
        name="particle",
        q=(x, y),
        u=(u1, u2),
        params=(m, g),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, -m * g]),
        energy=m / 2 * (u1**2 + u2**2) + m * g * y,
    )
    return MechanicalModel(**{**fields, **changes})


def refusal(**changes) -> InputError:
    with pytest.raises(InputError) as info:
        particle(**changes)
    return info.value


def test_the_particle_itself_constructs():
    assert particle().state_names == ("x", "y", "u1", "u2")


def test_a_coordinate_given_twice_is_refused_naming_it():
    err = refusal(q=(x, x))
    assert err.field == "model 'particle': q" and err.value == ["x", "x"]
    assert "x appears 2 times in q" in str(err)


def test_a_speed_that_is_also_a_coordinate_is_refused():
    err = refusal(u=(x, u2))
    assert err.field == "model 'particle': u"
    assert "x is a speed and already a coordinate" in str(err)


def test_a_speed_given_twice_and_a_parameter_named_like_the_state_or_t_are_refused():
    assert "u1 appears 2 times in u" in str(refusal(u=(u1, u1)))
    assert "x is a parameter and already a coordinate" in str(refusal(params=(m, g, sp.Symbol("x"))))
    assert "already a parameter" in str(refusal(params=(m, g, sp.Symbol("t", real=True))))


def test_an_unknown_symbol_in_P_is_refused_at_construction_naming_it_P_and_the_parameters():
    err = refusal(P=sp.Matrix([0, -m * g - k * y]))
    assert err.field == "model 'particle': P[1]" and err.value == ["k"]
    assert "unknown symbol k" in str(err)
    assert "parameters (m, g)" in err.allowed and "coordinates (x, y)" in err.allowed


def test_an_unknown_symbol_in_the_energy_is_refused_at_construction():
    err = refusal(energy=m / 2 * (u1**2 + u2**2) + k * y**2 / 2)
    assert err.field == "model 'particle': energy" and err.value == ["k"]
    assert "parameters (m, g)" in err.allowed


@pytest.mark.parametrize(
    ("field", "change"),
    [
        ("C[0, 1]", {"C": sp.Matrix([[1, k], [0, 1]])}),
        ("D[0]", {"D": sp.Matrix([k, 0])}),
        ("Q[1, 1]", {"Q": sp.diag(m, k)}),
        ("nonholonomic['drive']", {"nonholonomic": {"drive": u1 - k}, "u_independent": (u2,)}),
        ("holonomic['line']", {"holonomic": {"line": y - k * x}}),
        ("outputs['spring']", {"outputs": {"spring": k * y}}),
        ("monitors['height']", {"monitors": {"height": y - k}}),
    ],
)
def test_an_unknown_symbol_anywhere_is_refused_naming_the_field(field, change):
    err = refusal(**change)
    assert err.field == f"model 'particle': {field}" and err.value == ["k"]


def test_a_dynamicsymbol_or_a_derivative_left_in_is_refused():
    from sympy.physics.mechanics import dynamicsymbols

    X = dynamicsymbols("x")
    err = refusal(P=sp.Matrix([0, -m * g - X.diff()]))
    assert err.field == "model 'particle': P[1]" and "x(t)" in err.value
    assert "from_mechanics" in err.allowed
    assert refusal(q=(X, y)).field == "model 'particle': q"


def test_a_symbol_named_like_the_models_but_with_other_assumptions_is_refused_saying_so():
    err = refusal(energy=m * g * sp.Symbol("y"))  # not real, unlike the coordinate y
    assert err.value == ["y"] and "other assumptions" in str(err)


def test_a_speed_in_a_holonomic_constraint_is_refused():
    err = refusal(holonomic={"line": y - u1})
    assert err.field == "model 'particle': holonomic['line']"
    assert "may not depend on the speeds u1" in str(err)


def test_the_partition_names_speeds_and_coordinates_of_the_model_each_once():
    both = {"holonomic": {"line": y - x}}
    assert "not coordinates" in str(refusal(**both, q_dependent=(u1,)))
    assert "repeated" in str(refusal(**both, q_dependent=(y, y)))
    assert "not speeds" in str(refusal(**both, u_independent=(x,)))


def test_registering_a_system_with_an_unknown_symbol_fails_at_registration_not_at_its_first_run():
    from nmkane_core import Parameter, System, register, unregister

    def model():
        return particle(P=sp.Matrix([0, -m * g - k * y]))

    system = System(
        name="test-unknown-k",
        variants=model,
        parameters={"m": Parameter(1.0, 0.0, 10.0), "g": Parameter(9.81, 0.0, 100.0)},
        default_initial={"x": 0.0, "y": 1.0},
    )
    try:
        with pytest.raises(InputError, match=r"P\[1\]: got \['k'\] \(unknown symbol k\)"):
            register(system)
    finally:
        unregister("test-unknown-k")
