"""The ``nmkane`` subcommands: the core's own and those other packages contribute.

The core's own commands are listed here.  Other packages add theirs through the
entry-point group ``nmkane.commands`` (an entry names a :class:`Command`): that is how
the service contributes ``nmkane serve`` without the core importing it.
"""

from __future__ import annotations

from functools import lru_cache
from importlib.metadata import entry_points

from .command import Command

ENTRY_POINT_GROUP = "nmkane.commands"


def _unavailable(name: str, error: Exception) -> Command:
    """A contributed command whose package cannot be imported: say which extra installs it."""

    def run(_args) -> int:
        from ..errors import NmkaneError

        raise NmkaneError(f"'{name}' is not available here ({error}); install it with pip install 'nmkane[all]'")

    def add_arguments(p) -> None:
        p.add_argument("rest", nargs="*")

    return Command(name, f"(not available: {error})", add_arguments, run)


def contributed() -> list[Command]:
    """Commands other installed packages declare in the ``nmkane.commands`` entry-point group."""
    out = []
    for ep in sorted(entry_points(group=ENTRY_POINT_GROUP), key=lambda e: e.name):
        try:
            cmd = ep.load()
        except ImportError as e:
            cmd = _unavailable(ep.name, e)
        if isinstance(cmd, Command):
            out.append(cmd)
    return out


def builtin() -> list[Command]:
    from . import (
        analysis_cmd,
        bench_cmd,
        cache_cmd,
        figures_cmd,
        matrices_cmd,
        run_cmd,
        stability_cmd,
        sweep_cmd,
        tune_cmd,
    )

    return [
        run_cmd.COMMAND,
        matrices_cmd.COMMAND,
        analysis_cmd.ACCELERATIONS,
        analysis_cmd.LINEARIZE,
        stability_cmd.COMMAND,
        sweep_cmd.COMMAND,
        tune_cmd.COMMAND,
        bench_cmd.COMMAND,
        figures_cmd.COMMAND,
        cache_cmd.COMMAND,
    ]


@lru_cache(maxsize=1)
def all_commands() -> dict[str, Command]:
    commands = {c.name: c for c in builtin()}
    for c in contributed():
        commands.setdefault(c.name, c)
    return commands
