"""Drawing the figures with matplotlib, imported only inside :func:`draw_figure` and the
helpers it calls (``import nmkane_core`` must never load matplotlib).

Each ``draw(fig, runs)`` fills a matplotlib Figure from the runs of :mod:`.runs`; the
figure list with captions and texts is :mod:`.figure_specs`.
"""

from __future__ import annotations

import itertools
import re
from collections.abc import Callable
from typing import Protocol

import numpy as np

from .claims import drift
from .runs import T_FIG16, Runs
from .text import plain_caption


class Drawable(Protocol):
    """What :func:`draw_figure` needs of a figure (a :class:`~.figure_specs.FigureSpec` has it)."""

    @property
    def number(self) -> int: ...

    @property
    def caption(self) -> str: ...

    @property
    def draw(self) -> Callable:  # draw(fig, runs): fills the matplotlib Figure
        ...


__all__ = [
    "draw_figure",
    "draw_ah",
    "draw_ex2",
    "draw_fig4",
    "draw_fig6",
    "draw_fig7",
    "draw_fig9",
    "draw_fig16",
    "draw_fig18",
]

C_NC, C_LC, C_REF = "#1f4e9c", "#e07b00", "#222222"
C_M, C_N, C_DN = "#2a7d2a", "#c0392b", "#1f4e9c"


def _ah_series(ax, runs, name, ylabel, scale=1.0):
    oracle = runs.extra.get("oracle", {})
    drawn = False
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        ax.plot(r.t, r.state[name] * scale, color=C_NC, lw=2.2, label="NC (nonlinear constraints)")
        drawn = True
    if runs.ok("ah-linear"):
        r = runs["ah-linear"]
        ax.plot(r.t, r.state[name] * scale, color=C_LC, lw=1.2, ls="--", label="LC (linear constraints)")
        drawn = True
    if "state" in oracle:
        k = max(len(oracle["t"]) // 25, 1)
        ax.plot(
            oracle["t"][::k],
            oracle["state"][name][::k] * scale,
            "o",
            ms=3.5,
            mfc="none",
            color=C_REF,
            label="Kane's minimal eqs. (KanesMethod)",
        )
    ax.set_xlabel("t (s)")
    ax.set_ylabel(ylabel)
    if drawn:
        ax.legend(loc="best", fontsize=8)


def draw_ah(name, ylabel):
    def draw(fig, runs):
        _ah_series(fig.add_subplot(111), runs, name, ylabel)

    return draw


def draw_fig6(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (("ah-nonlinear", C_NC, "-", 2.2, "NC"), ("ah-linear", C_LC, "--", 1.2, "LC")):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.state["phi"], r.state["u1"], color=color, ls=ls, lw=lw, label=label)
    ax.set_xlabel(r"$\phi$ (rad)")
    ax.set_ylabel(r"$\dot{\theta}$ (rad/s)")
    ax.legend(fontsize=8)


def draw_fig7(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (("ah-nonlinear", C_NC, "-", 2.2, "NC"), ("ah-linear", C_LC, "--", 1.2, "LC")):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.state["x"], r.state["y"], color=color, ls=ls, lw=lw, label=label)
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        marks = list(range(0, len(r.t), max(len(r.t) // 4, 1)))
        for i in marks[1:]:
            ax.annotate(
                f"t = {r.t[i]:g} s",
                (r.state["x"][i], r.state["y"][i]),
                textcoords="offset points",
                xytext=(8, -4),
                fontsize=8,
            )
            ax.plot(r.state["x"][i], r.state["y"][i], "o", color=C_NC, ms=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=8, loc="lower left")
    _fig7_inset(ax, runs)


def draw_fig9(fig, runs):
    ax = fig.add_subplot(111)
    for key, color, ls, lw, label in (
        ("ah-linear", C_LC, "-", 1.6, "LC (linear constraints)"),
        ("ah-nonlinear", C_NC, "-", 2.0, "NC (nonlinear constraints)"),
    ):
        if runs.ok(key):
            r = runs[key]
            ax.plot(r.t, drift(r), color=color, ls=ls, lw=lw, label=label)
    ax.axhline(0, color="0.6", lw=0.6)
    ax.set_xlabel("t (s)")
    ax.set_ylabel(r"$\Delta E$ (J)")
    ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
    ax.legend(fontsize=8)


def draw_ex2(key, what, bound=None):
    """Figs. 11–15, 17: one run, φ or ΔE vs t (as the paper plots it), and below it the
    envelope of |·| on a log axis; ``bound`` = (value, label) draws the paper's bound."""

    def draw(fig, runs):
        gs = fig.add_gridspec(2, 1, height_ratios=(3, 2), hspace=0.08)
        ax = fig.add_subplot(gs[0])
        ax2 = fig.add_subplot(gs[1], sharex=ax)
        if not runs.ok(key):
            ax.text(0.5, 0.5, f"not run: {runs.errors.get(key)}", ha="center", transform=ax.transAxes, wrap=True)
            return
        r = runs[key]
        v = r.violation["surface"] if what == "phi" else drift(r)
        ax.plot(r.t, v, color=C_NC, lw=0.5)
        ax.axhline(0, color="0.6", lw=0.6)
        ax.set_ylabel(r"$\phi$ (m)" if what == "phi" else r"$\Delta E$ (J)")
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax.tick_params(labelbottom=False)
        a = np.abs(v)
        ax2.semilogy(r.t, np.maximum(a, 1e-300), color=C_NC, lw=0.4, alpha=0.35)
        env_t, env = _envelope(r.t, a, 100)
        ax2.semilogy(env_t, env, color=C_NC, lw=1.6, label="envelope (max per window)")
        hi = max(a.max(), bound[0] if bound else 0.0) * 3
        lo = max(env[env > 0].min() / 3, a.max() * 1e-8) if np.any(env > 0) else hi * 1e-8
        ax2.set_ylim(min(lo, hi / 100), hi)
        if bound:
            for y in (bound[0], -bound[0]):
                ax.axhline(y, color="#c0392b", ls="--", lw=1.0)
            ax2.axhline(bound[0], color="#c0392b", ls="--", lw=1.0, label=bound[1])
        ax2.set_ylabel(r"$|\phi|$ (m)" if what == "phi" else r"$|\Delta E|$ (J)")
        _log_ticks(ax2)
        ax2.set_xlabel("t (s)")
        ax2.legend(fontsize=8, loc="lower right")

    return draw


def _envelope(t, a, n):
    edges = np.linspace(0, len(a), n + 1).astype(int)
    tt, mm = [], []
    for i, j in itertools.pairwise(edges):
        if j > i:
            tt.append(t[(i + j - 1) // 2])
            mm.append(a[i:j].max())
    return np.array(tt), np.array(mm)


def _window_range(t, v, n):
    edges = np.linspace(0, len(v), n + 1).astype(int)
    tt, lo, hi = [], [], []
    for i, j in itertools.pairwise(edges):
        if j > i:
            tt.append(t[(i + j - 1) // 2])
            lo.append(v[i:j].min())
            hi.append(v[i:j].max())
    return np.array(tt), np.array(lo), np.array(hi)


def draw_fig16(fig, runs):
    gs = fig.add_gridspec(1, 2, width_ratios=(1.1, 1), wspace=0.25)
    ax = fig.add_subplot(gs[0])
    ax2 = fig.add_subplot(gs[1])
    # left: the whole hour as the range of y per 30 s window (the swings are too fast to draw)
    for key, color, label in (
        ("sp-1h-minimal", C_M, "M minimal"),
        ("sp-1h-damped", C_DN, "DN damped nonminimal (Γ1 = −20, Γ2 = −100)"),
        ("sp-1h-nonminimal", C_N, "N nonminimal (Γ1 = Γ2 = 0)"),
    ):
        if runs.ok(key):
            r = runs[key]
            tt, lo, hi = _window_range(r.t, r.state["y"], 120)
            if key == "sp-1h-damped":  # hatched, so that M's band shows through
                ax.fill_between(tt / 60, lo, hi, facecolor="none", edgecolor=color, hatch="////", lw=0, label=label)
            else:
                ax.fill_between(
                    tt / 60, lo, hi, color=color, alpha=0.3 if key == "sp-1h-minimal" else 0.8, lw=0, label=label
                )
            ax.plot(tt / 60, hi, color=color, lw=1.0)
            ax.plot(tt / 60, lo, color=color, lw=1.0)
    ax.axhline(0, color="0.4", lw=0.6, ls=":")
    ax.axhline(1, color="0.4", lw=0.6, ls=":")
    ax.set_yscale("symlog", linthresh=1.0, linscale=1.5)
    ax.set_ylim(-0.3, None)
    ax.set_xlabel("t (min)")
    ax.set_ylabel("y (m): range per 30 s window\n(symlog: linear below 1 m)")
    ax.set_title("the whole hour (bowl: 0 ≤ y ≤ l0 = 1 m, dotted)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    # right: the last seconds, sample by sample
    t1 = T_FIG16
    if runs.ok("sp-1h-reference"):
        ref = runs["sp-1h-reference"]
        w = ref.t >= t1 - 8
        ax2.plot(
            ref.t[w],
            ref.state["y"][w],
            color=C_REF,
            lw=2.6,
            alpha=0.3,
            label=f"reference: minimal, Δt = {ref.settings['dt']:g} s",
        )
    for key, color, label in (("sp-1h-minimal", C_M, "M (Δt = 0.1 s)"), ("sp-1h-damped", C_DN, "DN (Δt = 0.1 s)")):
        if runs.ok(key):
            r = runs[key]
            w = r.t >= t1 - 8
            ax2.plot(r.t[w], r.state["y"][w], ".-", color=color, lw=1.0, ms=3.5, label=label)
    ax2.set_xlim(t1 - 8, t1)
    ax2.set_ylim(-0.1, 1.6)
    ax2.set_xlabel("t (s)")
    ax2.set_ylabel("y (m)  (y = 1: bottom of the bowl)")
    ax2.set_title("the last 8 s (N is off the scale)", fontsize=9)
    ax2.legend(fontsize=7, loc="upper center", ncol=2, columnspacing=1.0, handlelength=1.5)


def draw_fig18(fig, runs):
    gs = fig.add_gridspec(2, 1, height_ratios=(3, 2), hspace=0.1)
    ax = fig.add_subplot(gs[0])
    ax2 = fig.add_subplot(gs[1], sharex=ax)
    series = (
        ("sp-fig18-baumgarte", "#1f4e9c", '"1" Baumgarte (Γ1 = −20, Γ2 = −100)'),
        ("sp-fig18-blajer", "#c0392b", '"2" Blajer (projection preset)'),
        ("sp-fig18-yoon", "#2a7d2a", '"3" Yoon et al. (projection preset)'),
    )
    floor = 1e-17
    missing = []
    window = float("nan")
    for key, color, label in series:
        if not runs.ok(key):
            missing.append(f"{label.split(' (')[0]}: not run ({runs.errors.get(key, '?')[:90]})")
            continue
        r = runs[key]
        a = np.maximum(np.abs(r.violation["surface"]), floor)
        env_t, env = _envelope(r.t, a, 250)
        window = r.t[-1] / 250
        ax.semilogy(env_t, env, color=color, lw=1.6, label=label)
        ax2.plot(
            r.t,
            drift(r),
            color=color,
            lw=1.2 if "blajer" not in key else 2.2,
            label=label.split(" (")[0],
            zorder=3 if "blajer" in key else 2,
        )
    for key, color, marker in (("sp-fig18-blajer", "#c0392b", "x"), ("sp-fig18-yoon", "#2a7d2a", "+")):
        pre = runs.extra.get(f"precorrection:{key}")
        if pre:
            name = "Blajer" if "blajer" in key else "Yoon et al."
            ax.semilogy(
                pre["t"],
                np.maximum(pre["values"], floor),
                marker,
                color=color,
                ms=3,
                alpha=0.6,
                label=f"{name}: |φ| one step before the correction (sampled)",
            )
    ax.axhline(2.22e-16, color="0.5", lw=0.8, ls=":", label="machine ε = 2.2e−16")
    ax.set_ylabel(r"$|\phi|$ (m)" + f"\nmax per {window:.2g} s window")
    top = max([float(np.max(line.get_ydata())) for line in ax.get_lines() if len(line.get_ydata())] + [1e-12])
    ax.set_ylim(floor / 2, top * 3e4)  # room above the curves for the legend
    _log_ticks(ax)
    ax.tick_params(labelbottom=False)
    ax.legend(fontsize=6.5, loc="upper center", ncol=2, framealpha=0.95)
    if missing:
        ax.text(0.02, 0.04, "\n".join(missing), transform=ax.transAxes, fontsize=7, color="#c0392b")
    ax2.axhline(0, color="0.6", lw=0.6)
    ax2.set_ylabel(r"$\Delta E$ (J)" + "\n(not in the paper)", fontsize=9)
    ax2.set_xlabel("t (s)")
    ax2.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
    ax2.legend(fontsize=7, loc="lower left")


def draw_fig4(fig, runs):
    ax = fig.add_subplot(111)
    _ah_series(ax, runs, "u1", r"$\dot{\theta}$ (rad/s)")
    ax.legend(loc="upper center", fontsize=8)
    if runs.ok("ah-nonlinear"):
        r = runs["ah-nonlinear"]
        ins = ax.inset_axes([0.52, 0.22, 0.45, 0.45])
        ins.semilogy(r.t, np.maximum(np.abs(r.state["u1"]), 1e-300), color=C_NC, lw=1.6)
        if runs.ok("ah-linear"):
            rl = runs["ah-linear"]
            ins.semilogy(rl.t, np.maximum(np.abs(rl.state["u1"]), 1e-300), color=C_LC, lw=1.0, ls="--")
        ins.set_title(r"$|\dot{\theta}|$ (rad/s), log scale", fontsize=8)
        ins.tick_params(labelsize=7)
        ins.grid(True, alpha=0.3)
        _log_ticks(ins)


def _fig7_inset(ax, runs, t_zoom=3.0):
    ins = ax.inset_axes([0.6, 0.42, 0.37, 0.5])
    for key, color, ls, lw in (("ah-nonlinear", C_NC, "-", 2.0), ("ah-linear", C_LC, "--", 1.0)):
        if runs.ok(key):
            r = runs[key]
            w = r.t <= t_zoom
            ins.plot(r.state["x"][w], r.state["y"][w], color=color, ls=ls, lw=lw)
    ins.set_title(f"first {t_zoom:g} s", fontsize=8)
    ins.set_aspect("equal", adjustable="datalim")
    ins.tick_params(labelsize=7)
    ins.grid(True, alpha=0.3)


def _wrap_caption(caption: str, width: int) -> str:
    """Greedy line wrap that never splits a $…$ mathtext span; widths count rendered characters."""
    lines: list[str] = []
    cur: list[str] = []
    n = 0
    for tok in re.findall(r"[^\s$]*\$[^$]*\$[^\s$]*|\S+", caption):
        w = len(plain_caption(tok))
        if cur and n + 1 + w > width:
            lines.append(" ".join(cur))
            cur, n = [], 0
        cur.append(tok)
        n += w + (1 if n else 0)
    lines.append(" ".join(cur))
    return "\n".join(lines)


def _log_ticks(ax):
    """Major decade labels only (minor labels crowd a log axis spanning less than a decade)."""
    from matplotlib.ticker import LogLocator, NullFormatter

    ax.yaxis.set_major_locator(LogLocator(base=10, numticks=12))
    ax.yaxis.set_minor_formatter(NullFormatter())


def draw_figure(spec: Drawable, runs: Runs, path: str) -> None:
    """Draw ``spec`` from ``runs`` under the paper's caption and save it as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    wide = spec.number == 16
    fig = Figure(
        figsize=(10.0 if wide else 7.0, 4.8 if spec.number in (11, 12, 13, 14, 15, 17, 18) else 4.4),
        dpi=130,
        layout="constrained",
    )
    spec.draw(fig, runs)
    for ax in fig.axes:
        ax.grid(True, which="major", alpha=0.3)
    fig.suptitle(_wrap_caption(spec.caption, 130 if wide else 88), fontsize=10.5)
    fig.savefig(path)
