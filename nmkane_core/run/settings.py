"""Run settings in: a mapping checked against the schema, every error as an :class:`InputError`.

:func:`validate_settings` applies :class:`~nmkane_core.schema.RunSettings`' own checks (types,
finite numbers, the ranges declared on its fields) strictly, as the REST service does, and
says what each field allows in the words every face uses (:func:`nmkane_core.schema.allowed`);
:func:`raise_all` reports several problems in one error.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..errors import InputError
from ..schema import RunSettings, allowed, field_range

__all__ = ["raise_all", "shown", "validate_settings"]

#: pydantic error types that mean "outside the field's declared range" (or not a number at all)
_RANGE_ERRORS = {
    "greater_than",
    "greater_than_equal",
    "less_than",
    "less_than_equal",
    "finite_number",
    "float_type",
    "int_type",
    "float_parsing",
    "int_parsing",
    "int_from_float",
}


def validate_settings(settings: Mapping) -> RunSettings:
    """The schema's checks (types, finite numbers, ranges) with errors as :class:`InputError`.

    ``settings``: a mapping of run settings (a dict; numpy scalars and arrays and tuples are
    taken as the numbers and lists they hold).  Validation is strict, as on the REST service:
    no booleans or numeric strings for numbers, no 2.0 for an integer.  Every violated field
    is named in one message (the error's ``errors`` lists them one by one).
    """
    from pydantic import ValidationError

    if not isinstance(settings, Mapping):
        raise InputError(
            "settings",
            shown(settings),
            "a mapping (dict) of run settings, e.g. {'dt': 0.01, 't_final': 20}",
            f"a {type(settings).__name__}",
        )
    try:
        return RunSettings.model_validate(_plain_data(dict(settings)), strict=True)
    except ValidationError as e:
        raise_all([_input_error(err) for err in e.errors()])
        raise AssertionError("unreachable") from None  # pragma: no cover


def _input_error(err) -> InputError:
    """One pydantic error as an :class:`InputError`: a number outside a field's declared range
    says the range (``a finite number in [1e-07, 10] s``), anything else pydantic's words."""
    field = ".".join(str(p) for p in err["loc"]) or "settings"
    value = shown(err.get("input"))
    name = str(err["loc"][0]) if len(err["loc"]) == 1 else ""
    if err["type"] in _RANGE_ERRORS and name in RunSettings.model_fields and field_range(name) is not None:
        if err["type"].startswith(("greater", "less")):
            reason = "out of range"
        else:
            reason = "not an integer" if err["type"].startswith("int") else "not a number"
        return InputError(field, value, allowed(name), reason)
    return InputError(field, value, _allowed_words(err["msg"]))


def _allowed_words(msg: str) -> str:
    """pydantic's "Input should be ..." as what is allowed: ``a finite number``, ``an integer``
    (from "a valid integer"), ``a value greater than 0``, ``'rk4' or 'dop853'``."""
    rest = msg.removeprefix("Input should be ")
    if rest == msg:
        return msg
    if rest.startswith("a valid "):
        noun = rest.removeprefix("a valid ")
        rest = ("an " if noun[:1] in "aeiou" else "a ") + noun
    return rest if rest.startswith(("a ", "an ", "'")) else f"a value {rest}"


def raise_all(errors: list[InputError]) -> None:
    """Raise the one error, or one :class:`InputError` naming every field (its ``errors``
    attribute keeps them one by one, for a REST answer with one item each)."""
    if not errors:
        return
    if len(errors) == 1:
        raise errors[0]
    first = errors[0]
    combined = InputError(first.field, first.value, first.allowed, first.reason)
    combined.args = ("; ".join(str(e) for e in errors) + f" ({len(errors)} problems)",)
    combined.errors = errors  # type: ignore[attr-defined]
    raise combined


def _plain_data(value, depth: int = 0):
    """numpy scalars and arrays, and tuples, as the Python numbers and lists they hold."""
    if depth > 8:
        return value
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, tuple):
        return [_plain_data(v, depth + 1) for v in value]
    if isinstance(value, list):
        return [_plain_data(v, depth + 1) for v in value]
    if isinstance(value, dict):
        return {k: _plain_data(v, depth + 1) for k, v in value.items()}
    return value


def shown(value, depth: int = 0):
    """``value``, or a short text standing for it when it is too large or deep to print."""
    if isinstance(value, bool) or value is None or isinstance(value, float):
        return value
    if isinstance(value, int):
        if abs(value) < 10**30:
            return value
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1:,} digits"
    if isinstance(value, str):
        return value if len(value) <= 200 else value[:200] + f"… ({len(value)} characters)"
    if isinstance(value, (list, tuple, dict)):
        if depth >= 4:
            return f"a {type(value).__name__} nested too deeply to show"
        items = list(value.items()) if isinstance(value, dict) else list(value)
        if len(items) > 20:
            return f"a {type(value).__name__} of {len(items)} items"
        if isinstance(value, dict):
            return {k: shown(v, depth + 1) for k, v in items}
        return type(value)(shown(v, depth + 1) for v in items)
    text = repr(value)
    return value if len(text) <= 200 else text[:200] + "…"
