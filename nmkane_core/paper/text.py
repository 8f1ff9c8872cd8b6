"""How the report writes things: numbers, figure lists, captions without mathtext, table cells."""

from __future__ import annotations

__all__ = ["num", "fig_label", "plain_caption", "md_cell"]


def num(v: float) -> str:
    """Three significant digits, in scientific notation outside [1e-3, 1e4)."""
    return f"{v:.3g}" if 1e-3 <= abs(v) < 1e4 or v == 0 else f"{v:.2e}"


def fig_label(figs) -> str:
    """``(2, 3, 4)`` → ``2–4``; ``(14, 17)`` → ``14, 17``."""
    figs = list(figs)
    if len(figs) > 2 and figs == list(range(figs[0], figs[-1] + 1)):
        return f"{figs[0]}–{figs[-1]}"
    return ", ".join(str(f) for f in figs)


def plain_caption(c: str) -> str:
    """A figure caption with its mathtext spans written as plain Unicode."""
    rep = {
        r"$\dot{\theta}$": "θ̇",
        r"$\dot{\phi}$": "φ̇",
        r"$\theta$": "θ",
        r"$\phi$": "φ",
        r"$\Delta E$": "ΔE",
        r"$\Gamma_1 = \Gamma_2 = 0$": "Γ1 = Γ2 = 0",
        r"$\Gamma_1 = -20$": "Γ1 = −20",
        r"$\Gamma_2 = -100$": "Γ2 = −100",
        r"$\Delta t = 0.01$": "Δt = 0.01",
        r"$\Delta t = 0.001$": "Δt = 0.001",
        r"$\Delta t = 0.1$": "Δt = 0.1",
        r"$y$": "y",
    }
    for k, v in rep.items():
        c = c.replace(k, v)
    return c


def md_cell(s: str) -> str:
    """Text safe inside one cell of a Markdown table."""
    return str(s).replace("|", "\\|").replace("\n", " ")
