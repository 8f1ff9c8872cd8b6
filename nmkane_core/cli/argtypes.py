"""argparse pieces shared by the ``nmkane`` subcommands: finite numbers, counts, NAME=VALUE, ``--systems``."""

from __future__ import annotations

import argparse
import math

__all__ = ["add_systems_option", "assignment", "finite", "positive_int"]


def finite(text: str) -> float:
    """argparse type: a finite float."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def finite_list(text: str) -> list[float]:
    """argparse type: comma-separated finite floats (``0,0.5,1``)."""
    return [finite(part) for part in text.split(",") if part.strip()]


def name_list(text: str) -> list[str]:
    """argparse type: comma-separated names (``a,b``; ``""``: none)."""
    return [part.strip() for part in text.split(",") if part.strip()]


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def assignment(text: str) -> tuple[str, float]:
    """argparse type: NAME=VALUE with a finite value."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), finite(value)


def add_systems_option(p: argparse.ArgumentParser) -> None:
    """``--systems PATH_OR_MODULE`` (repeatable): plug-in systems to load first."""
    p.add_argument(
        "--systems",
        action="append",
        default=[],
        metavar="PATH_OR_MODULE",
        help="a systems file (.py) or module to load first (repeatable; runs as Python code); "
        "also $NMKANE_SYSTEMS and the nmkane.systems entry points",
    )
