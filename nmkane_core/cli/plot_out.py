"""``nmkane run ... --plot Y[:X]``: a run's quantities drawn to a PNG.

Each ``--plot`` is one panel: ``Y`` against time, or ``Y:X`` (a phase portrait) ``Y``
against ``X``.  ``Y`` and ``X`` are expressions in the page's syntax, read by
:mod:`nmkane_core.analysis.expressions` (parsed and checked on a whitelist, never
``eval``'d), over the names the run offers.  Drawing needs matplotlib (the ``figures``
extra); it draws off-screen (Agg).
"""

from __future__ import annotations

from ..analysis import expressions as ex
from ..errors import InputError

__all__ = ["check_plot_out", "plot_file", "split_plot", "write_plots"]


def split_plot(text: str) -> tuple[str, str | None]:
    """``"Y:X"`` → (Y, X); ``"Y"`` → (Y, None); more than one colon is refused."""
    parts = text.split(":")
    if len(parts) > 2 or any(not p.strip() for p in parts):
        raise InputError("plot", text, "EXPR (against t) or EXPR:EXPR (the first against the second)", "bad form")
    return parts[0].strip(), (parts[1].strip() if len(parts) == 2 else None)


def check_plot_out(path: str | None) -> None:
    """Refuse a ``--plot-out`` that is not a PNG file name (before the run)."""
    if path is not None and not path.lower().endswith(".png"):
        raise InputError("plot_out", path, "a file name ending in .png", "unknown format")


def plot_file(system: str, path: str | None) -> str:
    """Where the plot goes: ``--plot-out`` or ``<system>-plot.png``."""
    return path or f"{system}-plot.png"


def _allowed(names) -> str:
    return (
        f"an expression of {', '.join(names)} (numbers, + - * / ^ %, the constants pi, e "
        f"and the functions {', '.join(ex.FUNCTIONS)})"
    )


def _series(text: str, values: dict, full: str):
    try:
        return ex.evaluate(ex.parse(text, values), values)
    except ex.ExpressionError as e:
        reason = str(e).split(" (known:", 1)[0]  # the names are listed as what is allowed
        raise InputError("plot", full, _allowed(values), reason) from None


def panels(run, plots: list[str]) -> list[tuple[str, object, str, object]]:
    """(x label, x values, y label, y values) of each ``--plot``; InputError names the bad one."""
    values = ex.quantities(run)
    out = []
    for text in plots:
        y, x = split_plot(text)
        xs = _series(x, values, text) if x is not None else values["t"]
        out.append((x or "t [s]", xs, y, _series(y, values, text)))
    return out


def write_plots(run, plots: list[str], path: str) -> str:
    """Draw each ``--plot`` of ``run`` as a panel of one PNG at ``path``; returns the path."""
    drawn = panels(run, plots)  # every expression checked before anything is drawn
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - matplotlib is in the figures and web extras
        raise InputError("plot", plots[0], "plots with matplotlib installed: pip install 'nmkane[figures]'") from None
    fig, axes = plt.subplots(len(drawn), 1, figsize=(7, 2.8 * len(drawn)), squeeze=False)
    for ax, (xlab, xs, ylab, ys) in zip(axes[:, 0], drawn, strict=True):
        ax.plot(xs, ys, lw=1.2)
        ax.set_xlabel(xlab)
        ax.set_ylabel(ylab)
        ax.grid(True, alpha=0.3)
    axes[0, 0].set_title(f"{run.system}: {run.status}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
