"""The command-line page: every ``nmkane`` command and option, from the argparse parsers.

The tables are committed in ``docs/cli.md`` between ``<!-- begin nmkane:NAME … -->`` and
``<!-- end nmkane:NAME -->`` (as the REST page's, see ``gen_rest``), so the page reads whole
in the repository; the site's build writes them afresh, and
``tests/docs/test_generated_reference.py`` fails when the committed text is stale.  Refresh
it with::

    python scripts/docs/gen_cli.py --write     # --check: exit 1 if docs/cli.md is stale

Usage lines are wrapped at 88 columns (the width of a code block), whatever the terminal.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

from _md import DOCS, table
from gen_rest import command_line, splice

WIDTH = "88"  # argparse wraps usage lines at $COLUMNS


@contextlib.contextmanager
def _columns() -> Iterator[None]:
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        yield
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old


def _parser() -> argparse.ArgumentParser:
    from nmkane_core.cli import _build_parser
    from nmkane_core.cli.commands import all_commands

    return _build_parser(all_commands())


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _helps(parser: argparse.ArgumentParser) -> dict[str, str]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return {a.dest: a.help or "" for a in action._choices_actions}
    return {}


def _option(action: argparse.Action) -> str:
    if action.option_strings:
        names = ", ".join(f"`{o}`" for o in action.option_strings)
    else:
        names = f"`{action.metavar or action.dest}`"
    if action.nargs != 0 and action.option_strings:
        if action.choices:
            names += " `{" + ",".join(str(c) for c in action.choices) + "}`"
        else:
            names += f" `{action.metavar or action.dest.upper()}`"
    return names


def _default(action: argparse.Action) -> str:
    d = action.default
    if d in (None, argparse.SUPPRESS, False) or action.nargs == 0:
        return ""
    if isinstance(d, list) and not d:
        return ""
    return f"`{d}`"


def _command(path: list[str], parser: argparse.ArgumentParser, help_text: str, level: int) -> list[str]:
    out = [f"{'#' * level} `{' '.join(path)}`", ""]
    if help_text:
        out += [help_text[0].upper() + help_text[1:] + ("" if help_text.endswith(".") else "."), ""]
    if parser.description and parser.description != help_text:
        out += [parser.description, ""]
    usage = parser.format_usage().removeprefix("usage: ").strip()
    out += ["```text", usage, "```", ""]
    rows = [
        (_option(a), a.help % {"default": a.default} if a.help and "%(" in a.help else a.help, _default(a))
        for a in parser._actions
        if not isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)) and a.help != argparse.SUPPRESS
    ]
    if rows:
        out += [table(("argument", "meaning", "default"), rows)]
    helps = _helps(parser)
    for name, sub in _subparsers(parser).items():
        out += _command([*path, name], sub, helps.get(name, ""), level + 1)
    return out


def parts() -> dict[str, str]:
    """The generated blocks of ``docs/cli.md``, from the parsers now."""
    with _columns():
        parser = _parser()
        helps = _helps(parser)
        commands = _subparsers(parser)
        rows = [(f"[`nmkane {n}`](#nmkane-{n})", helps.get(n, "")) for n in commands]
        body: list[str] = []
        for name, sub in commands.items():
            body += _command(["nmkane", name], sub, helps.get(name, ""), 3)
    return {"cli-summary": table(("command", "what it does"), rows), "cli-commands": "\n".join(body)}


def render(text: str) -> str:
    """``docs/cli.md``'s text ``text`` with its generated blocks made now."""
    return splice(text, parts(), "scripts/docs/gen_cli.py")


def pages() -> dict[str, str]:
    return {"cli.md": render((DOCS / "cli.md").read_text())}


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the checkout's nmkane_core, backend, web
    sys.exit(command_line("cli.md", render))
