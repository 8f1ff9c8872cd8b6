"""Declaring a system: names bound once and by name, checked when it is registered.

Each test names the mistake a user makes (the findings of the user-systems issue) and
checks that it is caught at registration with a message that says what to change, or that
the value is bound by name where it used to be bound by position.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from nmkane_core import InputError, Parameter, System, get_system, register, simulate
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import default_state
from nmkane_core.run.registry import unregister

NAME = "test-declared-knife-edge"


def knife_edge_model():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, inertia = sp.symbols("m I", positive=True)
    return MechanicalModel(
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m, inertia),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, inertia),
        P=sp.zeros(3, 1),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},
        u_independent=(u1, u3),
        energy=m / 2 * (u1**2 + u2**2) + inertia / 2 * u3**2,
    )


def declare(**over) -> System:
    kw = dict(
        name=NAME,
        variants=knife_edge_model,
        parameters={"m": Parameter(1.0, 0.0, 1e3, "kg"), "I": Parameter(0.5, 0.0, 1e3, "kg m²")},
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u3": 1.0},
        default_dt=0.001,
        default_t_final=1.0,
    )
    kw.update(over)
    return System(**kw)


@pytest.fixture(autouse=True)
def _forget():
    yield
    unregister(NAME)


def test_names_come_from_the_model_said_once():
    s = register(declare())
    assert built(s).coordinates == ("x", "y", "theta") and built(s).speeds == ("u1", "u2", "u3")
    assert built(s).independent == ("x", "y", "theta", "u1", "u3")  # q (no holonomic) and u_I
    assert s.variant_names == ("default",) and default_state(s)["u2"] == 0.0  # completed


def test_parameters_are_bound_by_name_not_by_declaration_order():
    """Declared in the other order than the model's params (m, I): the energy must still
    be m/2 v² + I/2 ω² with m = 2 and I = 0.25 (by position it would be 0.25/2 + 2/2)."""
    register(declare(parameters={"I": Parameter(0.25, 0.0, 10.0), "m": Parameter(2.0, 0.0, 10.0)}))
    run = simulate({"system": NAME, "t_final": 0.01})
    assert run.energy[0] == pytest.approx(2.0 / 2 * 1.0 + 0.25 / 2 * 1.0, rel=1e-12)


def test_parameters_may_be_keyed_by_the_models_own_symbols():
    import sympy as sp

    m, inertia = sp.symbols("m I", positive=True)
    s = register(declare(parameters={m: Parameter(3.0, 0.0, 10.0), inertia: Parameter(1.0, 0.0, 10.0)}))
    assert s.param_names == ("m", "I")
    assert simulate({"system": NAME, "t_final": 0.01}).energy[0] == pytest.approx(3.0 / 2 + 1.0 / 2)


@pytest.mark.parametrize(
    "params,needle",
    [
        ({"m": Parameter(1.0, 0, 10)}, "declare I"),  # one missing
        (
            {"m": Parameter(1.0, 0, 10), "I": Parameter(1.0, 0, 10), "k": Parameter(1.0, 0, 10)},
            "remove k (no symbol of the model)",
        ),  # not a symbol
    ],
)
def test_parameters_that_do_not_match_the_model_are_refused_at_registration(params, needle):
    with pytest.raises(InputError) as e:
        register(declare(parameters=params))
    assert e.value.field.endswith("parameters") and needle in str(e.value)


def test_a_parameter_default_outside_its_range_is_refused():
    with pytest.raises(InputError) as e:
        declare(parameters={"m": Parameter(-1.0, 0.0, 10.0), "I": Parameter(1.0, 0.0, 10.0)})
    assert "parameters.m" in e.value.field and "out of range" in str(e.value)


def test_positional_parameter_names_of_the_old_api_get_a_message_that_says_what_to_write():
    with pytest.raises(InputError) as e:
        Parameter("m", 1.0, 0.0, 1e3)  # type: ignore[arg-type]
    assert "Parameter(default, min, max, unit, description)" in str(e.value)


def test_an_unknown_initial_name_is_refused_at_registration_naming_default_initial():
    with pytest.raises(InputError) as e:
        register(declare(default_initial={"x": 0.0, "psi": 1.0}))
    assert "default_initial.psi" in e.value.field and "theta" in str(e.value)


def test_an_inconsistent_full_default_state_is_refused_at_registration():
    full = {"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u2": 0.5, "u3": 1.0}  # slips sideways
    with pytest.raises(InputError) as e:
        register(declare(default_initial=full))
    assert e.value.field.endswith("default_initial") and "no_side_slip" in str(e.value)


def test_an_unknown_variant_name_in_the_declaration_is_refused():
    with pytest.raises(InputError) as e:
        declare(variants={"a": knife_edge_model}, completion_variant="b")
    assert "completion_variant" in e.value.field and "a" in e.value.allowed


def test_a_factory_that_fails_is_reported_with_the_variant_name():
    def broken():
        raise ZeroDivisionError("typo in the model")

    with pytest.raises(InputError) as e:
        register(declare(variants=broken))
    assert "variant default" in e.value.field and "typo in the model" in str(e.value)


def test_register_name_must_match_the_systems_own_name():
    with pytest.raises(InputError) as e:
        register("another-name")(declare)
    assert "two names" in str(e.value)


def test_registering_a_name_again_replaces_it_and_warns_when_it_was_used():
    register(declare())
    first = simulate({"system": NAME, "t_final": 0.01}).energy[0]
    with pytest.warns(UserWarning, match="registered again"):
        register(declare(parameters={"m": Parameter(4.0, 0.0, 10.0), "I": Parameter(0.5, 0.0, 10.0)}))
    assert get_system(NAME).parameter("m").default == 4.0
    assert simulate({"system": NAME, "t_final": 0.01}).energy[0] == pytest.approx(first + 1.5)
    with pytest.warns(UserWarning):
        register(declare())  # replaces the used one (warns)...
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # ...but this one was never used: no warning
        register(declare())


def test_a_system_with_one_variant_needs_no_variant_vocabulary():
    register(declare())
    run = simulate({"system": NAME, "t_final": 0.2})
    assert run.status == "ok" and run.settings["model"] == "default"
    assert math.isclose(float(np.hypot(run.state["u1"][-1], run.state["u2"][-1])), 1.0, rel_tol=1e-9)
