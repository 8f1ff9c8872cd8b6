"""The plot data of one request's runs (the shown run first, then the compare runs): energy
drift, log₁₀ |violation| per constraint, and a typed quantity — against time or against
another quantity (a phase portrait: :func:`phase_data`), all drawn by uPlot.

Every series says in its label what it is and how it is drawn: the shown run solid, each
compare run in its colour and line style, named ("linear, dashed"), so the legend reads
without the colours.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from nmkane_core.analysis import expressions as ex

from . import plots as pl
from .geometry import decimate


def style(j: int, color: str) -> dict:
    """uPlot series style of the j-th run (0: the shown one, solid)."""
    return {"stroke": color, **({"dash": pl.DASHES[(j - 1) % len(pl.DASHES)]} if j else {})}


def run_suffix(j: int, label: str, many: bool) -> str:
    """How a series names its run: nothing for the shown run alone, else the run and its line style."""
    if not many:
        return ""
    return f" — {label}" if j == 0 else f" — {label}, {pl.DASH_NAMES[(j - 1) % len(pl.DASH_NAMES)]}"


def on_main(main, r, v):
    """``v`` of run ``r`` on the main run's times."""
    return np.asarray(v, float) if r is main else np.interp(main.t, r.t, v)


def energy(runs: dict) -> pl.Curves:
    labels, many = list(runs), len(runs) > 1
    main = runs[labels[0]]
    dEs = []
    for r in runs.values():
        e = np.zeros(len(r.t)) if r.energy is None else np.asarray(r.energy, float)
        dEs.append(on_main(main, r, e - e[0] if len(e) else e))
    factor, unit = pl.readable(dEs, "J")
    names = [f"ΔE{run_suffix(j, lab, many)}" for j, lab in enumerate(labels)]
    out = pl.curves(main.t, [d / factor for d in dEs], names, y_label=f"ΔE = E − E(0) [{unit}]")
    out.styles = [style(j, pl.RUN_COLORS[j % len(pl.RUN_COLORS)]) for j in range(len(labels))]
    return out


def violation(runs: dict) -> pl.Curves:
    """One colour per constraint, one line style per run."""
    labels, many = list(runs), len(runs) > 1
    main = runs[labels[0]]
    ys, names, styles = [], [], []
    for j, (lab, r) in enumerate(runs.items()):
        for c, (name, v) in enumerate(r.violation.items()):
            ys.append(pl.log10_abs(on_main(main, r, v)))
            names.append(f"{name}{run_suffix(j, lab, many)}")
            styles.append(style(j, pl.COLORS[c % len(pl.COLORS)]))
    if not ys:
        ys, names, styles = [np.full(len(main.t), math.log10(pl.LOG_FLOOR))], ["(no constraints)"], [style(0, "#888")]
    out = pl.curves(main.t, ys, names, y_label="log₁₀ |φ| (violation)")
    out.styles = styles
    return out


@dataclass
class Phase:
    """A phase portrait: y against x for each run (values divided by the axis' readable factor,
    named in its title; see :func:`phase_data`)."""

    xs: list[np.ndarray]
    ys: list[np.ndarray]
    ts: list[np.ndarray]
    labels: list[str]
    x_label: str
    y_label: str
    styles: list[dict] = field(default_factory=list)
    equal: bool = False  # the two axes share a unit: drawn to equal scale (see :func:`same_unit`)

    def at(self, t_now: float) -> tuple[float, float]:
        """The shown run's point at t_now (the last output row at or before it)."""
        t = self.ts[0]
        k = min(max(int(np.searchsorted(t, t_now, side="right")) - 1, 0), len(t) - 1)
        return float(_finite(self.xs[0][k])), float(_finite(self.ys[0][k]))

    def box(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """The data's x and y extents over every run (finite values)."""
        x = pl.data_range(self.xs) or (0.0, 0.0)
        y = pl.data_range(self.ys) or (0.0, 0.0)
        return x, y


def scaled_label(text: str, unit: str) -> str:
    """An axis title: the typed text, and the factor its values were divided by (``×1e-6``)."""
    return f"{text} [{unit}]" if unit else text


@functools.lru_cache(maxsize=64)
def length_coordinates(system: str) -> frozenset[str]:
    """The coordinates that are lengths, as the system's declared visuals tell: those that move
    the origin of a declared frame and turn none (a body's x and y on the ground; not its heading
    angle, which turns it).  Empty for a system that declares no visuals (the model declares no units)."""
    from nmkane_core.kernel.built import built
    from nmkane_core.run.registry import get_system

    moves: set[str] = set()
    turns: set[str] = set()
    try:
        core = get_system(system)
        if core.visuals is None:
            return frozenset()
        for frame in core.visuals().frames:
            moves |= {str(s) for c in frame.origin for s in getattr(c, "free_symbols", ())}
            if frame.rotation is not None:
                turns |= {str(s) for s in getattr(frame.rotation, "free_symbols", ())}
        names = set(built(core).state_names)
    except Exception:  # a plot's scale must never take the page down: no unit known, own scales
        return frozenset()
    return frozenset((moves - turns) & names)  # not the parameters (a radius)


def same_unit(system: str, x_text: str, y_text: str) -> bool:
    """Whether a phase portrait's axes share a unit: each is one coordinate alone (``y``, not
    ``2*y`` or ``u1``) and both are lengths by :func:`length_coordinates`."""
    lengths = length_coordinates(system)
    return x_text.strip() in lengths and y_text.strip() in lengths


def quantity(runs: dict, y_text: str, x_text: str = "t") -> pl.Curves | Phase:
    """A typed quantity of every run: against time (x_text ``t``) or against another one.
    Raises :class:`~nmkane_core.analysis.expressions.ExpressionError` when the text names what a run lacks."""
    labels, many = list(runs), len(runs) > 1
    main = runs[labels[0]]
    ys, xs = [], []
    for r in runs.values():
        q = ex.quantities(r)
        ys.append(ex.evaluate(ex.parse(y_text, q), q))
        xs.append(ex.evaluate(ex.parse(x_text, q), q))
    styles = [style(j, pl.RUN_COLORS[j % len(pl.RUN_COLORS)]) for j in range(len(labels))]
    names = [f"{y_text}{run_suffix(j, lab, many)}" for j, lab in enumerate(labels)]
    if x_text.strip() == "t":
        on_t = [on_main(main, r, y) for r, y in zip(runs.values(), ys, strict=True)]
        factor, unit = pl.readable(on_t, "")  # tick values neither "0 0 0" nor too long for the axis
        out = pl.curves(main.t, [y / factor for y in on_t], names, y_label=scaled_label(y_text, unit))
        out.styles = styles
        return out
    ts = [np.asarray(r.t, float) for r in runs.values()]
    equal = same_unit(main.system, x_text, y_text)
    xs = [np.asarray(x, float) * np.ones(len(t)) for x, t in zip(xs, ts, strict=True)]  # a constant made a series
    ys = [np.asarray(y, float) * np.ones(len(t)) for y, t in zip(ys, ts, strict=True)]
    if equal:  # one factor for both axes: a metre stays as long across as up
        fx, ux = pl.readable(xs + ys, "")
        fy, uy = fx, ux
    else:
        (fx, ux), (fy, uy) = pl.readable(xs, ""), pl.readable(ys, "")
    return Phase(
        [x / fx for x in xs],
        [y / fy for y in ys],
        ts,
        names,
        scaled_label(x_text, ux),
        scaled_label(y_text, uy),
        styles,
        equal=equal,
    )


def _finite(v: np.ndarray) -> np.ndarray:
    """Values a plot can take: NaN as 0, ±∞ as ±1e300 (as :func:`web.plots.curves`)."""
    return np.nan_to_num(np.asarray(v, float), nan=0.0, posinf=1e300, neginf=-1e300)


def phase_data(phase: Phase, budget: int) -> tuple[np.ndarray, ...]:
    """uPlot data of a phase portrait: the runs' x values one after the other, and per run its y
    values on its own stretch and NaN on the others' (drawn as no line: the plot's scales are
    fixed and its series not auto-ranged, so no NaN reaches a range), each run thinned to an
    even share of ``budget`` points.

    uPlot's aligned mode draws a series point after point in the order given, so x need not
    increase, as long as the x scale's range holds every x strictly inside (uPlot's window of
    rows is then all of them) and there are fewer points than 4 per pixel of the plot's width
    (above that uPlot thins a line pixel column by pixel column, which assumes increasing x):
    the panel's budget stays below that."""
    n = len(phase.xs)
    share = max(2, budget // max(n, 1))
    keeps = [decimate(len(x), share) for x in phase.xs]
    x = np.concatenate([_finite(xr[k]) for xr, k in zip(phase.xs, keeps, strict=True)])
    ys = []
    start = 0
    for yr, k in zip(phase.ys, keeps, strict=True):
        y = np.full(len(x), np.nan)
        y[start : start + len(k)] = _finite(yr[k])
        ys.append(y)
        start += len(k)
    return (x, *ys)
