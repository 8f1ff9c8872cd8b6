"""The command-line page: every ``nmkane`` command and option, from the argparse parsers."""

from __future__ import annotations

import argparse

from _md import fill, table


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


def pages() -> dict[str, str]:
    parser = _parser()
    helps = _helps(parser)
    commands = _subparsers(parser)
    summary = table(("command", "what it does"), [(f"[`nmkane {n}`](#nmkane-{n})", helps.get(n, "")) for n in commands])
    body: list[str] = []
    for name, sub in commands.items():
        body += _command(["nmkane", name], sub, helps.get(name, ""), 3)
    return {"cli.md": fill("cli.md", {"cli-summary": summary, "cli-commands": "\n".join(body)})}
