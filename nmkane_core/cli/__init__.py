"""The ``nmkane`` command.

Subcommands are :class:`~nmkane_core.cli.commands.Command` records: the core's own (``run``,
``matrices``, ``bench``, ``figures``, ``cache``) and those other installed packages add
through the entry-point group ``nmkane.commands`` (the service adds ``serve``), so the core
imports neither the service nor the web app.

Errors in options or input print one line naming the option, the value and what is
allowed, and exit with code 2 (no traceback).
"""

from __future__ import annotations

import os
import sys

from ..errors import InputError, NmkaneError
from .command import Command
from .commands import all_commands
from .common import PROG, Parser, input_error_line, notice_if_slow
from .run_cmd import format_summary

__all__ = ["Command", "main", "entry", "format_summary", "notice_if_slow"]


def _build_parser(commands: dict[str, Command]) -> Parser:
    parser = Parser(
        prog=PROG,
        description="Nonminimal Kane's equations (Bajodah, Hodges & Chen 2005): "
        "simulate, serve the REST API and 3D web app, benchmark, reproduce the paper.",
    )
    sub = parser.add_subparsers(dest="command", required=True, parser_class=Parser)
    for cmd in commands.values():
        cmd.add_arguments(sub.add_parser(cmd.name, help=cmd.help))
    return parser


def main(argv: list[str] | None = None) -> int:
    """Parse ``argv`` and run the subcommand; returns the exit code."""
    commands = all_commands()
    args = _build_parser(commands).parse_args(argv)
    try:
        return commands[args.command].run(args)
    except InputError as e:
        print(f"{PROG} {args.command}: error: {input_error_line(e)}", file=sys.stderr)
        return 2
    except NmkaneError as e:
        print(f"{PROG} {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # output piped into `head` and closed: not an error of ours
        sys.stderr.close()
        return 0


def entry() -> None:
    """The ``nmkane`` console command: :func:`main`, then a quick exit.

    Tearing the interpreter down (freeing every module's objects one by one: sympy's, numpy's)
    takes a noticeable part of a cached ``nmkane run`` and does nothing a finished command
    needs: files are closed by then, so the output streams are flushed and the process ends
    with ``os._exit``.  Commands that run servers
    (``quick_exit=False``) and errors escaping ``main`` take the ordinary exit.
    """
    args = sys.argv[1:]
    try:
        code = main(args)
    except SystemExit as e:  # argparse: --help, usage errors
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
    cmd = all_commands().get(args[0]) if args else None
    if cmd is not None and not cmd.quick_exit:
        sys.exit(code)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):  # a closed pipe or stream: nothing left to flush
        pass
    os._exit(code)
