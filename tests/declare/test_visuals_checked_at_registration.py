"""A system's visuals are checked when it is registered (issue 44, item 9): a shape or frame
that uses a name which is neither a state name nor a parameter is refused by ``register``,
naming the shape, its field and the name, not later when the visuals are first compiled."""

from __future__ import annotations

import pytest

from nmkane_core import InputError, register
from nmkane_core.declare import visuals as v
from nmkane_core.run.registry import get_system, unregister
from tests.declare.test_user_system_declaration import NAME, declare


@pytest.fixture(autouse=True)
def _forget():
    yield
    unregister(NAME)


def _visuals_with_unknown_k():
    import sympy as sp

    from nmkane_core import plain_symbols

    x, y = plain_symbols("x y")
    k = sp.Symbol("k")  # neither a state name nor a parameter (m, I)
    return v.Visuals(frames=(v.Frame("body", (x, y, 0)),), shapes=(v.sphere("ball", k, frame="body"),))


def _visuals_of_known_names():
    import sympy as sp

    from nmkane_core import plain_symbols

    x, y = plain_symbols("x y")
    m = sp.Symbol("m", positive=True)
    return v.Visuals(frames=(v.Frame("body", (x, y, 0)),), shapes=(v.sphere("ball", m / 10, frame="body"),))


def test_register_refuses_a_visual_using_an_unknown_symbol_naming_the_shape_and_the_symbol():
    with pytest.raises(InputError) as caught:
        register(declare(visuals=_visuals_with_unknown_k))
    assert caught.value.field == "visuals.ball.radius" and caught.value.value == "k"
    assert "unknown name" in str(caught.value)
    with pytest.raises(InputError):  # and nothing was registered
        get_system(NAME)


def test_register_accepts_visuals_of_state_names_and_parameters():
    s = register(declare(visuals=_visuals_of_known_names))
    assert get_system(NAME) is s
