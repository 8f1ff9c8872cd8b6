"""``nmkane figures``: the paper's figures and the claims report (needs the ``figures`` extra)."""

from __future__ import annotations

import argparse

from .command import Command


def _add_arguments(figs: argparse.ArgumentParser) -> None:
    figs.add_argument("--out", default="figures", help="output directory (default ./figures)")
    figs.add_argument("--quick", action="store_true", help="shorter horizons where the claim allows")


def _run(args: argparse.Namespace) -> int:
    from ..figures import make_figures

    report = make_figures(args.out, progress=None, quick=args.quick)
    print(report.summary_text() if hasattr(report, "summary_text") else report)
    return 0


COMMAND = Command("figures", "regenerate the paper's figures and the claims report", _add_arguments, _run)
