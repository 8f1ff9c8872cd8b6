"""A physical parameter's declaration: default, allowed range, unit and meaning."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import InputError

__all__ = ["Parameter"]


@dataclass(frozen=True)
class Parameter:
    """A physical parameter's metadata: default value, allowed range, unit, meaning.

    Declared under the model's symbol (or its name) in ``System(parameters={...})``; the
    name is filled in from that key.  The range is ``(min, max]`` (``[min, max]`` with
    ``min_inclusive``)."""

    default: float
    min: float = -math.inf
    max: float = math.inf
    unit: str = ""
    description: str = ""
    min_inclusive: bool = False
    name: str = ""

    def __post_init__(self):
        if isinstance(self.default, str):
            raise InputError(
                "Parameter.default",
                self.default,
                "a number: Parameter(default, min, max, unit, description), declared under its "
                "symbol or name in System(parameters={m: Parameter(1.0, 0, 10, 'kg')})",
                "not a number",
            )
        if self.name:
            self.check(self.default, f"parameters.{self.name}.default")

    def check(self, value, field_path: str) -> float:
        if isinstance(value, bool) or (not isinstance(value, (int, float)) and not hasattr(value, "__float__")):
            raise InputError(field_path, value, self.allowed(), "not a number")
        try:
            v = float(value)
        except (TypeError, ValueError):
            raise InputError(field_path, value, self.allowed(), "not a number") from None
        if not math.isfinite(v):
            raise InputError(field_path, value, self.allowed(), "not finite")
        low_ok = v >= self.min if self.min_inclusive else v > self.min
        if not low_ok or v > self.max:
            raise InputError(field_path, value, self.allowed(), "out of range")
        return v

    def allowed(self) -> str:
        lo = "[" if self.min_inclusive else "("
        return f"a finite number in {lo}{self.min:g}, {self.max:g}]" + (f" {self.unit}" if self.unit else "")
