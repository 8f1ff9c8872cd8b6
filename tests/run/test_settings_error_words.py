"""A settings error says what is allowed in a sentence that reads (issue 44: it said
"allowed: a value a finite number")."""

import pytest

from nmkane_core.errors import InputError
from nmkane_core.run.settings import validate_settings


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"params": {"m": float("nan")}}, "params.m: got nan; allowed: a finite number"),
        ({"switching": 3}, "switching: got 3; allowed: a boolean"),
        ({"system": 3}, "system: got 3; allowed: a string"),
    ],
)
def test_pydantic_errors_read_as_what_is_allowed(settings, message):
    with pytest.raises(InputError) as e:
        validate_settings({"system": "sliding-particle", **settings})
    assert str(e.value) == message
    assert "a value a " not in str(e.value)
