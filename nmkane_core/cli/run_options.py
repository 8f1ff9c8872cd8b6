"""The run settings as command-line options, made from :class:`~nmkane_core.schema.RunSettings`.

Every field of the schema is an option named after it (``t_final`` → ``--t-final``), with the
field's description and declared range as its help and its choices from the field's type;
the schema stays the one definition.  A few fields read better another way on a command
line and are spelled here once: the system is the positional ``SYSTEM``, ``params`` and
``initial`` are repeated ``--set NAME=VALUE`` and ``--init NAME=VALUE``, ``switching`` is
``--no-switching``, ``project_initial`` and ``error_estimate`` are flags (``--project-initial``,
``--error-estimate``), and a gain is a scalar
(Γ·I) — the library and REST also take matrices.
"""

from __future__ import annotations

import argparse
import types
import typing
from typing import Any, Literal

from ..schema import RunSettings, allowed, field_range
from .argtypes import add_systems_option, assignment, finite, finite_list, name_list, positive_int

__all__ = ["SPELLED", "add_run_options", "option_of", "settings_from_args"]

#: fields with a command-line spelling of their own (see the module docstring)
SPELLED = {
    "system": "SYSTEM",
    "params": "--set",
    "initial": "--init",
    "switching": "--no-switching",
    "project_initial": "--project-initial",
    "error_estimate": "--error-estimate",
}
GAINS = ("gamma", "gamma1", "gamma2")
#: options of the commands that are not run settings, by the field name errors use
COMMAND_OPTIONS = {"out": "--out", "time_limit": "--time-limit", "plot": "--plot", "plot_out": "--plot-out"}


def option_of(field: str) -> str:
    """The command-line spelling of a settings field (``params.rho`` -> ``--set rho``)."""
    if field.startswith("params."):
        return f"--set {field.split('.', 1)[1]}"
    if field.startswith("initial."):
        return f"--init {field.split('.', 1)[1]}"
    if field in SPELLED:
        return SPELLED[field]
    if field in COMMAND_OPTIONS:
        return COMMAND_OPTIONS[field]
    if field in RunSettings.model_fields:
        return "--" + field.replace("_", "-")
    return field


def _members(annotation) -> tuple:
    """The members of a union annotation (``float | None`` → (float, NoneType))."""
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        return typing.get_args(annotation)
    return (annotation,)


def _argument(name: str, choices: dict[str, tuple[str, ...]]) -> dict[str, Any]:
    """argparse keywords for one schema field: its type or choices, and its help."""
    info = RunSettings.model_fields[name]
    members = [m for m in _members(info.annotation) if m is not type(None)]
    kw: dict[str, Any] = {"dest": name, "default": None}
    literal = [m for m in members if typing.get_origin(m) is Literal]
    lists = [typing.get_args(m)[0] for m in members if typing.get_origin(m) is list]
    if name in choices:
        kw.update(choices=choices[name], metavar="NAME")
    elif literal:
        kw["choices"] = typing.get_args(literal[0])
    elif bool in members:
        kw["choices"] = ("yes", "no")
    elif name in GAINS or float in members:
        kw["type"] = finite
    elif lists:  # comma-separated on the command line
        numbers = lists[0] is float
        kw.update(type=finite_list if numbers else name_list, metavar="T1,T2,..." if numbers else "NAME,...")
    elif int in members:
        kw["type"] = positive_int
    help_text = info.description or ""
    if field_range(name) is not None:
        help_text += f" ({allowed(name)}"
        help_text += f"; default {info.default:g})" if isinstance(info.default, (int, float)) else ")"
    if name in choices:
        help_text += ": " + " | ".join(choices[name])
    if name in GAINS:
        help_text += " (on the command line a scalar)"
    kw["help"] = help_text.replace("%", "%%")
    return kw


def add_run_options(parser: argparse.ArgumentParser, choices: dict[str, tuple[str, ...]] | None = None) -> None:
    """The run settings as options of ``parser`` (every command that runs a system).

    ``choices``: allowed values of string fields known only above the schema (the integrator
    names)."""
    from ..integrate.methods import integrator_names

    choices = {"integrator": integrator_names(), **(choices or {})}
    parser.add_argument(
        "system", metavar="SYSTEM", help=_help("system").removesuffix("; default: the catalogue's first")
    )
    add_systems_option(parser)
    for name in RunSettings.model_fields:
        if name not in SPELLED:
            parser.add_argument(option_of(name), **_argument(name, choices))
    parser.add_argument("--no-switching", action="store_true", help=_help("switching", "turn it off"))
    parser.add_argument("--project-initial", action="store_true", help=_help("project_initial"))
    parser.add_argument("--error-estimate", action="store_true", help=_help("error_estimate"))
    meta = "NAME=VALUE"
    parser.add_argument(
        "--set", type=assignment, action="append", default=[], metavar=meta, help=_help("params", "e.g. --set rho=4")
    )
    parser.add_argument(
        "--init",
        type=assignment,
        action="append",
        default=[],
        metavar=meta,
        help=_help("initial", "e.g. --init u1=0.5"),
    )


def _help(name: str, extra: str = "") -> str:
    text = RunSettings.model_fields[name].description or ""
    return (text + (f" ({extra})" if extra else "")).replace("%", "%%")


def settings_from_args(args: argparse.Namespace) -> dict:
    """The run settings (as the REST API takes them) from parsed run options: the options given."""
    settings: dict[str, Any] = {
        "system": args.system,
        "params": dict(args.set),
        "initial": dict(args.init),
        "switching": not args.no_switching,
        "project_initial": args.project_initial,
        "error_estimate": args.error_estimate,
    }
    for name, info in RunSettings.model_fields.items():
        value = getattr(args, name, None)
        if name in SPELLED or value is None:
            continue
        if bool in _members(info.annotation):
            value = value == "yes"
        settings[name] = value
    return settings
