"""The plot data of one request's runs (the shown run first, then the compare runs): energy
drift, log₁₀ |violation| per constraint, and a typed quantity — against time (uPlot) or
against another quantity (a phase portrait, drawn as an image: uPlot's aligned mode needs
increasing x).

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
    """A phase portrait: y against x for each run (drawn as an image, see :func:`draw_phase`)."""

    xs: list[np.ndarray]
    ys: list[np.ndarray]
    ts: list[np.ndarray]
    labels: list[str]
    x_label: str
    y_label: str
    styles: list[dict] = field(default_factory=list)
    equal: bool = False  # the two axes share a unit: drawn to equal scale (see :func:`same_unit`)


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
        out = pl.curves(
            main.t, [on_main(main, r, y) for r, y in zip(runs.values(), ys, strict=True)], names, y_label=y_text
        )
        out.styles = styles
        return out
    ts = [np.asarray(r.t, float) for r in runs.values()]
    return Phase(xs, ys, ts, names, x_text, y_text, styles, equal=same_unit(main.system, x_text, y_text))


def draw_phase(phase: Phase, t_now: float, width_px: int = 460) -> np.ndarray:
    """The phase portrait as an RGBA image, each run's point at t_now marked."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_px / 100, width_px / 100 * 0.72), dpi=100)
    ax = fig.add_subplot()
    for x, y, t, lab, st in zip(phase.xs, phase.ys, phase.ts, phase.labels, phase.styles, strict=True):
        x, y = np.nan_to_num(x), np.nan_to_num(y)
        keep = decimate(len(x), 4000)
        dash = st.get("dash")
        ax.plot(x[keep], y[keep], color=st["stroke"], lw=1.4, dashes=dash if dash else (None, None), label=lab)
        k = min(max(int(np.searchsorted(t, t_now, side="right")) - 1, 0), len(t) - 1)
        ax.plot([x[k]], [y[k]], "o", color=st["stroke"], ms=6)
    ax.set_xlabel(phase.x_label)
    ax.set_ylabel(phase.y_label)
    ax.grid(True, alpha=0.3)
    if phase.equal:  # a metre is as long across as up: the data's box widened to the image's shape
        ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{phase.y_label} against {phase.x_label} (● now, t = {t_now:.2f} s)", fontsize=9)
    if len(phase.labels) > 1:
        ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.array(canvas.buffer_rgba(), dtype=np.uint8)
