"""``nmkane figures [--out DIR] [--quick] [--no-progress] [--strict]`` (also
``python -m nmkane_core.paper``)."""

from __future__ import annotations

import argparse
import sys

__all__ = ["add_arguments", "run", "main"]


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="figures", help="output directory (default ./figures)")
    p.add_argument("--quick", action="store_true", help="shorter horizons where the claim allows")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--strict", action="store_true", help="exit 1 when a claim fails or could not be checked")


def run(args: argparse.Namespace) -> int:
    """Make the figures and the report; print the claims.  Exit 1 when a figure could not be
    drawn, or (``--strict``) when a claim fails or could not be checked."""
    from .claims import FAIL, NOT_RUN
    from .make import make_figures

    report = make_figures(args.out, progress=False if args.no_progress else None, quick=args.quick)
    print(report.summary_text())
    n = report.counts
    if any(f.error for f in report.figures):
        return 1
    return 1 if args.strict and (n[FAIL] or n[NOT_RUN]) else 0


def main(argv: list[str] | None = None) -> int:
    from . import __doc__ as package_doc

    p = argparse.ArgumentParser(prog="nmkane figures", description=(package_doc or "").split("\n")[0])
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
