"""A subcommand as data: :class:`Command` (name, help, arguments, action)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Command:
    """One ``nmkane`` subcommand.

    ``add_arguments(parser)`` declares its options; ``run(args) -> exit code`` does the
    work (an :class:`~nmkane_core.errors.InputError` it raises is printed as one line,
    exit 2).  ``quick_exit``: end the process with ``os._exit`` once done (a finished
    command has nothing left to tear down; servers do and take the ordinary exit)."""

    name: str
    help: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]
    quick_exit: bool = True
