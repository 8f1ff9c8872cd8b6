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

A sweep's size is counted from its text (NUM, a list's length, ``samples``) and checked
against ``max_points`` before any value is made: ``gamma1=0:1:10000000`` over a limit of
10,000 is refused at once, not after building ten million values.  A sample's ``seed`` is an
integer in [0, `SEED_MAX`] (2³² − 1).
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
    "SEED_MAX",
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
#: The largest Latin-hypercube seed (seeds are integers in [0, SEED_MAX]; numpy takes any
#: non-negative integer, JSON and the service's store only 64-bit ones).
SEED_MAX = 2**32 - 1
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


@dataclass(frozen=True)
class _AxisText:
    """An axis as written: checked and counted, its values not made yet (`_values` makes them)."""

    name: str
    option: str
    text: str
    count: int
    ends: tuple[float, float] | None = None  # START, STOP of NAME=START:STOP:NUM
    log: bool = False
    items: tuple = ()  # the values of NAME=V1,V2,...


def _read_axis(text: str, log: bool = False) -> _AxisText:
    """Check the form of ``--grid``/``--log-grid`` ``text`` and count its values (NUM, or the
    list's length) without making them."""
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
        if log and (start == 0 or stop == 0 or (start > 0) != (stop > 0)):
            raise InputError(option, text, FORMS["log-grid"], "START and STOP must be nonzero, of one sign")
        return _AxisText(name, option, text, num, ends=(start, stop), log=log)
    if log:
        raise InputError(option, text, FORMS["log-grid"], "a list is not a log grid; use --grid NAME=V1,V2,...")
    items = [s.strip() for s in rest.split(",")]
    if any(not s for s in items):
        raise InputError(option, text, FORMS["grid"], "an empty list entry")
    if name in _WORD_FIELDS:
        return _AxisText(name, option, text, len(items), items=tuple(items))
    return _AxisText(name, option, text, len(items), items=tuple(_number(s, option, text, name) for s in items))


def _values(a: _AxisText) -> Axis:
    """The axis of a counted text, its values made (``a.count`` of them)."""
    values: tuple = a.items
    if a.ends is not None:
        start, stop = a.ends
        if a.log:
            sign = 1.0 if start > 0 else -1.0
            vals = sign * np.logspace(math.log10(abs(start)), math.log10(abs(stop)), a.count)
            vals[0], vals[-1] = start, stop  # the ends exactly as written
        else:
            vals = np.linspace(start, stop, a.count)
        values = tuple(float(v) for v in vals)
        if a.name in _INT_FIELDS:
            values = tuple(round(v) for v in values)
    if len(set(values)) != len(values):
        raise InputError(a.option, a.text, "distinct values", "a value repeats")
    return Axis(a.name, values)


def _too_many(size: int, max_points: int, parts: list[str]) -> InputError:
    # a product of many NUMs is written by its order of magnitude (str() of a huge int is refused)
    runs = f"{size:,} runs" if size < 10**15 else f"about 10^{int(size.bit_length() * math.log10(2))} runs"
    shown = parts if len(parts) <= 8 else [*parts[:8], f"… {len(parts) - 8} more"]
    return InputError("--grid", runs, f"at most {max_points:,} runs per sweep", "too many: " + " × ".join(shown))


def parse_axis(text: str, log: bool = False, max_points: int = MAX_POINTS) -> Axis:
    """``NAME=START:STOP:NUM`` (linear, or log with ``log``) or ``NAME=V1,V2,...`` (linear only);
    more than ``max_points`` values are refused before any is made."""
    a = _read_axis(text, log)
    if a.count > max_points:
        raise _too_many(a.count, max_points, [f"{a.name} {a.count:,}"])
    return _values(a)


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


def _check_seed(seed) -> None:
    if seed is None:
        return
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)):
        raise InputError("--seed", seed, f"an integer in [0, {SEED_MAX}]", "not an integer")
    if not 0 <= seed <= SEED_MAX:
        raise InputError("--seed", seed, f"an integer in [0, {SEED_MAX}]", "out of range")


def sweep_spec(
    grid=(), log_grid=(), sample=(), samples: int | None = None, seed: int | None = None, max_points: int = MAX_POINTS
) -> SweepSpec:
    """A `SweepSpec` from the texts of ``--grid``, ``--log-grid`` and ``--sample`` options.

    The number of runs (the product of the axes' NUMs and list lengths, times ``samples``) is
    counted from the texts and refused over ``max_points`` before any value is made; ``seed``
    is an integer in [0, `SEED_MAX`] (or None: a fresh sample each time)."""
    texts = [_read_axis(t) for t in grid] + [_read_axis(t, log=True) for t in log_grid]
    spec = SweepSpec()
    for text in sample:
        name, rng = parse_sample(text)
        spec.sample[name] = rng
    names = [a.name for a in texts] + list(spec.sample)
    for n in names:
        if names.count(n) > 1:
            raise InputError("--grid", n, "each NAME varied once", f"{n} is varied twice")
    if not names:
        raise InputError("--grid", None, "at least one --grid, --log-grid or --sample NAME=...", "nothing varies")
    _check_seed(seed)
    if spec.sample:
        if samples is None:
            raise InputError("--samples", None, "a positive integer with --sample", "missing")
        if not 1 <= samples <= max_points:
            raise InputError("--samples", samples, f"an integer in [1, {max_points:,}]")
        spec.samples, spec.seed = samples, seed
    elif samples is not None:
        raise InputError("--samples", samples, "--samples only with --sample NAME=LOW:HIGH", "nothing to sample")
    counts = [(a.name, a.count) for a in texts] + ([("samples", spec.samples)] if spec.sample else [])
    size = math.prod(n for _, n in counts)  # exact: Python's integers do not overflow
    if size > max_points:
        raise _too_many(size, max_points, [f"{name} {n:,}" for name, n in counts])
    spec.axes = [_values(a) for a in texts]  # only now, at most max_points values each
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
