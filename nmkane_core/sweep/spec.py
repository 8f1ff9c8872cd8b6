"""Sweep specifications: what varies, over which values, and the run settings of each point.

A varied NAME is a run-settings field (``gamma``, ``gamma1``, ``gamma2``, ``dt``, ``t_final``,
``integrator``, ...), ``params.NAME`` (a physical parameter) or ``initial.NAME`` (an initial
value).  Values come from

* ``NAME=START:STOP:NUM`` — NUM evenly spaced values, both ends included (``--grid``);
* ``NAME=V1,V2,...`` — a list; numbers or words such as ``rk4`` (``--grid``);
* ``NAME=START:STOP:NUM`` on a log scale (``--log-grid``; START and STOP of one sign, not 0);
* ``NAME=LOW:HIGH`` — a Latin hypercube sample (``--sample``, with ``samples`` and ``seed``).

Grids combine as a Cartesian product; samples are drawn jointly (one hypercube) and, if
grids are given too, every sample point is combined with every grid point.  Every error is
an [`InputError`][nmkane_core.InputError] naming the option, the text and what is allowed.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = [
    "MAX_POINTS",
    "SETTINGS_FIELDS",
    "Axis",
    "SweepSpec",
    "apply_point",
    "parse_axis",
    "parse_sample",
    "point_key",
    "sweep_spec",
]

#: Run-settings fields a sweep may vary (besides ``params.NAME`` and ``initial.NAME``).
SETTINGS_FIELDS = (
    "gamma",
    "gamma1",
    "gamma2",
    "dt",
    "t_final",
    "integrator",
    "model",
    "formulation",
    "projection",
    "projection_weight",
    "projection_iterations",
    "projection_jacobian",
    "rtol",
    "atol",
    "rcond_min",
    "rcond_switch",
    "every",
)
_WORD_FIELDS = ("integrator", "model", "formulation", "projection", "projection_weight", "projection_jacobian")
_INT_FIELDS = ("projection_iterations", "every")
MAX_POINTS = 10_000_000
FORMS = {
    "grid": "NAME=START:STOP:NUM or NAME=V1,V2,...",
    "log-grid": "NAME=START:STOP:NUM (START, STOP of one sign, not 0)",
    "sample": "NAME=LOW:HIGH with LOW < HIGH",
}


@dataclass(frozen=True)
class Axis:
    """One varied name and its values (in command-line order)."""

    name: str
    values: tuple


@dataclass
class SweepSpec:
    """The grid axes (a Cartesian product) and the Latin-hypercube ranges of a sweep."""

    axes: list[Axis] = field(default_factory=list)
    sample: dict[str, tuple[float, float]] = field(default_factory=dict)
    samples: int = 0
    seed: int | None = None

    @property
    def names(self) -> list[str]:
        """The varied names, grids first then samples (the output's first columns)."""
        return [a.name for a in self.axes] + list(self.sample)

    def __len__(self) -> int:
        n = math.prod(len(a.values) for a in self.axes)
        return n * (self.samples if self.sample else 1)

    def sample_points(self) -> np.ndarray:
        """The Latin hypercube, ``samples`` × len(sample), scaled to the ranges."""
        from scipy.stats import qmc

        lo = np.array([r[0] for r in self.sample.values()])
        hi = np.array([r[1] for r in self.sample.values()])
        unit = qmc.LatinHypercube(d=len(self.sample), seed=self.seed).random(self.samples)
        return qmc.scale(unit, lo, hi)

    def points(self) -> Iterator[dict]:
        """Every point as {name: value}, lazily (a grid of 10⁵ points is never a list)."""
        grid = itertools.product(*[a.values for a in self.axes])
        if not self.sample:
            for combo in grid:
                yield dict(zip(self.names, combo, strict=True))
            return
        lhs = [tuple(float(v) for v in row) for row in self.sample_points()]
        for combo in grid:
            for row in lhs:
                yield dict(zip(self.names, combo + row, strict=True))


def _check_name(name: str, option: str, text: str) -> str:
    name = name.strip()
    head, _, tail = name.partition(".")
    if (head in ("params", "initial") and tail) or name in SETTINGS_FIELDS:
        return name
    raise InputError(
        option, text, f"NAME one of {', '.join(SETTINGS_FIELDS)}, params.NAME or initial.NAME", f"unknown name {name!r}"
    )


def _number(text: str, option: str, whole: str, name: str):
    try:
        v = float(text)
    except ValueError:
        raise InputError(option, whole, FORMS[option.lstrip("-")], f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise InputError(option, whole, FORMS[option.lstrip("-")], f"{text!r} is not finite")
    if name in _INT_FIELDS:
        if v != int(v):
            raise InputError(option, whole, f"whole numbers for {name}", f"{text!r} is not an integer")
        return int(v)
    return v


def _count(text: str, option: str, whole: str) -> int:
    try:
        n = int(text)
    except ValueError:
        raise InputError(option, whole, FORMS[option.lstrip("-")], f"NUM {text!r} is not an integer") from None
    if not 1 <= n <= MAX_POINTS:
        raise InputError(option, whole, f"NUM in [1, {MAX_POINTS:,}]", f"NUM = {n}")
    return n


def parse_axis(text: str, log: bool = False) -> Axis:
    """``NAME=START:STOP:NUM`` (linear, or log with ``log``) or ``NAME=V1,V2,...`` (linear only)."""
    option = "--log-grid" if log else "--grid"
    name, sep, rest = text.partition("=")
    if not sep or not rest.strip():
        raise InputError(option, text, FORMS[option[2:]], "no '='" if not sep else "no values")
    name = _check_name(name, option, text)
    rest = rest.strip()
    if ":" in rest:
        parts = rest.split(":")
        if len(parts) != 3:
            raise InputError(option, text, FORMS[option[2:]], f"{len(parts)} fields between ':'")
        start, stop = (_number(p, option, text, "") for p in parts[:2])
        num = _count(parts[2], option, text)
        if log:
            if start == 0 or stop == 0 or (start > 0) != (stop > 0):
                raise InputError(option, text, FORMS["log-grid"], "START and STOP must be nonzero, of one sign")
            sign = 1.0 if start > 0 else -1.0
            vals = sign * np.logspace(math.log10(abs(start)), math.log10(abs(stop)), num)
            vals[0], vals[-1] = start, stop  # the ends exactly as written
        else:
            vals = np.linspace(start, stop, num)
        values: tuple = tuple(float(v) for v in vals)
        if name in _INT_FIELDS:
            values = tuple(round(v) for v in values)
    elif log:
        raise InputError(option, text, FORMS["log-grid"], "a list is not a log grid; use --grid NAME=V1,V2,...")
    else:
        items = [s.strip() for s in rest.split(",")]
        if any(not s for s in items):
            raise InputError(option, text, FORMS["grid"], "an empty list entry")
        if name in _WORD_FIELDS:
            values = tuple(items)
        else:
            values = tuple(_number(s, option, text, name) for s in items)
    if len(set(values)) != len(values):
        raise InputError(option, text, "distinct values", "a value repeats")
    return Axis(name, values)


def parse_sample(text: str) -> tuple[str, tuple[float, float]]:
    """``NAME=LOW:HIGH`` → (name, (low, high))."""
    name, sep, rest = text.partition("=")
    if not sep:
        raise InputError("--sample", text, FORMS["sample"], "no '='")
    name = _check_name(name, "--sample", text)
    if name in _WORD_FIELDS or name in _INT_FIELDS:
        raise InputError(
            "--sample", text, "a real-valued NAME (use --grid for words and integers)", f"{name} is not real-valued"
        )
    parts = rest.split(":")
    if len(parts) != 2:
        raise InputError("--sample", text, FORMS["sample"], f"{len(parts)} fields between ':'")
    lo, hi = (_number(p, "--sample", text, name) for p in parts)
    if not lo < hi:
        raise InputError("--sample", text, FORMS["sample"], "LOW is not below HIGH")
    return name, (lo, hi)


def sweep_spec(
    grid=(), log_grid=(), sample=(), samples: int | None = None, seed: int | None = None, max_points: int = MAX_POINTS
) -> SweepSpec:
    """A `SweepSpec` from the texts of ``--grid``, ``--log-grid`` and ``--sample`` options."""
    spec = SweepSpec()
    for text in grid:
        spec.axes.append(parse_axis(text))
    for text in log_grid:
        spec.axes.append(parse_axis(text, log=True))
    for text in sample:
        name, rng = parse_sample(text)
        spec.sample[name] = rng
    names = spec.names
    for n in names:
        if names.count(n) > 1:
            raise InputError("--grid", n, "each NAME varied once", f"{n} is varied twice")
    if not names:
        raise InputError("--grid", None, "at least one --grid, --log-grid or --sample NAME=...", "nothing varies")
    if spec.sample:
        if samples is None:
            raise InputError("--samples", None, "a positive integer with --sample", "missing")
        if not 1 <= samples <= max_points:
            raise InputError("--samples", samples, f"an integer in [1, {max_points:,}]")
        spec.samples, spec.seed = samples, seed
    elif samples is not None:
        raise InputError("--samples", samples, "--samples only with --sample NAME=LOW:HIGH", "nothing to sample")
    if len(spec) > max_points:
        raise InputError("--grid", f"{len(spec):,} runs", f"at most {max_points:,} runs per sweep", "too many")
    return spec


def apply_point(base: dict, point: dict) -> dict:
    """The run settings of one point: ``base`` with the point's values in place."""
    s = dict(base)
    s["params"] = dict(base.get("params") or {})
    s["initial"] = dict(base.get("initial") or {})
    for name, v in point.items():
        head, _, tail = name.partition(".")
        if head in ("params", "initial") and tail:
            s[head][tail] = v
        else:
            s[name] = v
    return s


def _key_part(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return str(v)
    if isinstance(v, (int, float, np.integer, np.floating)):
        return repr(float(v))
    try:
        return repr(float(v))
    except (TypeError, ValueError):
        return str(v)


def point_key(point: dict, names: list[str]) -> tuple[str, ...]:
    """A point's identity in the output (resume skips points whose key is there): its values,
    floats by their exact repr (a CSV round trip keeps them)."""
    return tuple(_key_part(point[n]) for n in names)
