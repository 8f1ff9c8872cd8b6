""":func:`make_figures`: make the runs, measure the claims, draw the figures, write the report."""

from __future__ import annotations

import json
import os
import sys
import time

import numpy as np

from .claims import FAIL, evaluate_claims
from .drawing import draw_figure
from .figure_specs import FIGURES, FigureResult, FigureSpec, facts
from .report import Report
from .rerun import run_doc
from .runs import Runs, collect_runs

__all__ = ["make_figures"]


def make_figures(out_dir: str, progress: bool | None = None, quick: bool = False, runs: Runs | None = None) -> Report:
    """Run everything, draw Figures 2–9 and 11–18 into ``out_dir`` and write the report there.

    ``progress=None`` shows progress bars when stderr is a terminal.  ``quick`` shortens the
    horizons where a claim allows it (see :mod:`nmkane_core.paper`).  ``runs``: the runs of
    :func:`collect_runs` made beforehand (then ``quick`` is theirs, and their time counts in
    the report's timings as if they had been made here).
    """
    t0 = time.perf_counter()
    if progress is None:
        progress = sys.stderr.isatty()
    os.makedirs(out_dir, exist_ok=True)
    if runs is None:
        t_runs = time.perf_counter()
        runs = collect_runs(quick=quick, progress=progress)
        runs_s = time.perf_counter() - t_runs
    else:
        quick, runs_s = runs.quick, runs.wall_s
        t0 -= runs_s
    claims = evaluate_claims(runs)
    measured = facts(runs, {c.key: c for c in claims})

    t_fig = time.perf_counter()
    results: list[FigureResult] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(FIGURES), unit="fig", desc="figures", leave=False)
    try:
        for spec in FIGURES:
            results.append(_figure(spec, runs, claims, measured, out_dir))
            if bar is not None:
                bar.update(1)
    finally:
        if bar is not None:
            bar.close()
    figures_s = time.perf_counter() - t_fig

    run_docs = {key: run_doc(key, runs) for key in runs.settings}
    timings = {
        "runs_s": runs_s,
        "integration_s (sum over runs, 2 threads)": float(sum(r.summary["wall_time_s"] for r in runs.results.values())),
        "oracle_s": float(runs.extra.get("oracle", {}).get("wall_s", 0.0)),
        "figures_s": figures_s,
    }
    report = Report(out_dir, quick, results, claims, run_docs, timings)
    report.timings["total_s"] = time.perf_counter() - t0
    paths = {
        "md": os.path.join(out_dir, "report.md"),
        "html": os.path.join(out_dir, "report.html"),
        "json": os.path.join(out_dir, "report.json"),
    }
    _write(paths["md"], report.to_markdown())
    _write(paths["html"], report.to_html())
    _write(paths["json"], json.dumps(report.to_json(), indent=1, default=_json_default, ensure_ascii=False))
    report.files = paths
    return report


def _figure(spec: FigureSpec, runs: Runs, claims: list, measured: dict, out_dir: str) -> FigureResult:
    """Draw one figure (a failure is recorded, not raised) and gather its claims and text."""
    fname = f"fig{spec.number:02d}_{spec.slug}.png"
    err = None
    path = os.path.join(out_dir, fname)
    try:
        draw_figure(spec, runs, path)
    except Exception as e:  # one broken figure must not lose the others or the report
        err = f"{type(e).__name__}: {e}"
        if os.path.exists(path):  # never show a stale image from an earlier run
            os.remove(path)
    fig_claims = [c for c in claims if spec.number in c.figures]
    explain = _explain(spec.explain, measured)
    if spec.number != 18 and any(c.status == FAIL for c in fig_claims):  # Fig. 18's text follows the numbers
        explain = (
            "[A claim of this figure FAILS now (see the table); the text below describes what "
            "the paper expects.] " + explain
        )
    return FigureResult(spec.number, fname, spec.caption, explain, list(spec.runs), fig_claims, spec.note, err)


def _explain(text: str, measured: dict) -> str:
    try:
        return text.format(**measured)
    except (KeyError, ValueError, IndexError):
        return text


def _json_default(o):
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.bool_,)):
        return bool(o)
    raise TypeError(type(o).__name__)


def _write(path: str, text: str) -> None:
    tmp = path + ".tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(tmp, path)
