"""``nmkane figures``: the paper's figures and the claims report (see :mod:`nmkane_core.paper`;
drawing needs the ``figures`` extra)."""

from __future__ import annotations

import argparse

from .command import Command


def _add_arguments(p: argparse.ArgumentParser) -> None:
    from ..paper.cli import add_arguments

    add_arguments(p)


def _run(args: argparse.Namespace) -> int:
    from ..paper.cli import run

    return run(args)


COMMAND = Command("figures", "regenerate the paper's figures and the claims report", _add_arguments, _run)
