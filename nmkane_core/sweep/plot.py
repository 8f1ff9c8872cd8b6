"""A sweep's metric drawn: lines over one varied name, a heatmap over two (matplotlib,
imported only here; the ``figures`` extra)."""

from __future__ import annotations

import math

from ..errors import InputError, NmkaneError

__all__ = ["DEFAULT_METRIC", "metric_values", "plot_sweep"]

DEFAULT_METRIC = "log10_max_violation"


def _max_violation(row: dict) -> float | None:
    vals = [v for k, v in row.items() if k.startswith("max_abs_violation.") and isinstance(v, (int, float))]
    return max(vals) if vals else None


def metric_values(rows: list[dict], metric: str, columns: list[str]) -> list[float]:
    """The metric of each row (NaN where a run has none): a column name, ``max_violation``
    (the largest over constraints) or ``log10_`` before either."""
    log = metric.startswith("log10_")
    base = metric[6:] if log else metric
    if base != "max_violation" and base not in columns:
        allowed = ", ".join(
            ["max_violation", *[c for c in columns if c.startswith(("max_abs", "final", "steps", "wall"))]]
        )
        raise InputError("--metric", metric, f"{allowed} (or log10_ before any)", "unknown metric")
    out = []
    for r in rows:
        v = _max_violation(r) if base == "max_violation" else r.get(base)
        if not isinstance(v, (int, float)) or r.get("status") != "ok":
            out.append(math.nan)
            continue
        v = float(v)
        if log:
            v = math.log10(abs(v)) if v != 0 else math.nan
        out.append(v)
    return out


def plot_sweep(
    rows: list[dict],
    columns: list[str],
    names: list[str],
    path: str,
    metric: str = DEFAULT_METRIC,
    title: str | None = None,
) -> None:
    """Draw ``metric`` over the sweep's one or two varied ``names`` into ``path`` (PNG, SVG, PDF)."""
    if len(names) not in (1, 2):
        raise InputError(
            "--plot", path, "a sweep of one varied name (lines) or two (heatmap)", f"{len(names)} names vary"
        )
    values = metric_values(rows, metric, columns)
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise NmkaneError("--plot needs matplotlib: pip install 'nmkane[figures]'") from None
    import numpy as np

    fig, ax = plt.subplots(figsize=(6.4, 4.8), dpi=110)
    if len(names) == 1:
        xs = [r[names[0]] for r in rows]
        if all(isinstance(x, (int, float)) for x in xs):
            order = sorted(range(len(xs)), key=lambda i: xs[i])
            ax.plot([xs[i] for i in order], [values[i] for i in order], "o-")
        else:
            ax.plot([str(x) for x in xs], values, "o")
        ax.set_xlabel(names[0])
        ax.set_ylabel(metric)
    else:
        xs = sorted({r[names[0]] for r in rows}, key=_sortable)
        ys = sorted({r[names[1]] for r in rows}, key=_sortable)
        if len(xs) * len(ys) <= 4 * len(rows):  # a grid: a heatmap
            z = np.full((len(ys), len(xs)), np.nan)
            ix, iy = {x: i for i, x in enumerate(xs)}, {y: i for i, y in enumerate(ys)}
            for r, v in zip(rows, values, strict=True):
                z[iy[r[names[1]]], ix[r[names[0]]]] = v
            im = ax.imshow(z, origin="lower", aspect="auto", cmap="viridis")
            ax.set_xticks(
                range(len(xs)),
                [f"{x:.3g}" if isinstance(x, float) else str(x) for x in xs],
                rotation=45 if len(xs) > 6 else 0,
            )
            ax.set_yticks(range(len(ys)), [f"{y:.3g}" if isinstance(y, float) else str(y) for y in ys])
        else:  # scattered samples
            im = ax.scatter(  # type: ignore[assignment]
                [r[names[0]] for r in rows], [r[names[1]] for r in rows], c=values, cmap="viridis"
            )
        fig.colorbar(im, ax=ax, label=metric)
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
    ax.set_title(title or f"{metric} ({len(rows)} runs)")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _sortable(v):
    return (0, v, "") if isinstance(v, (int, float)) else (1, 0, str(v))
