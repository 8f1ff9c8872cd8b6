"""``nmkane accelerations SYSTEM`` and ``nmkane linearize SYSTEM``: the equations of motion
at a state (see :mod:`nmkane_core.analysis.at_state`)."""

from __future__ import annotations

import argparse
import json

from .argtypes import add_systems_option, assignment, finite
from .command import Command
from .common import load_plugged_systems


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("system", metavar="SYSTEM")
    add_systems_option(p)
    p.add_argument("--model")
    p.add_argument("--formulation")
    p.add_argument(
        "--at",
        type=assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="the state: independent values (the others taken from the system's default state, "
        "the dependent ones completed from the constraints) or every coordinate and speed",
    )
    p.add_argument(
        "--set", type=assignment, action="append", default=[], metavar="NAME=VALUE", help="a physical parameter"
    )
    p.add_argument("--json", action="store_true", help="machine-readable output")


def _state(args):
    from ..kernel.built import built
    from ..run.registry import get_system

    load_plugged_systems(args)
    system = get_system(args.system)
    variant = getattr(args, system.option) or None
    params = dict(args.set)
    # independent values only: the rest from the defaults, dependent ones completed; a full
    # state as it is (checked against the constraints by the analysis)
    given = dict(args.at)
    if len(given) < len(built(system).state_names):
        from ..errors import InputError
        from ..run.initial import initial_state

        try:
            _, state = initial_state(system, system.check_variant(variant), system.resolve_params(params), given)
        except InputError as e:  # name the option of this command, not `run --init`
            field = e.field.replace("initial.", "--at ", 1) if e.field.startswith("initial.") else e.field
            raise InputError(field.replace("initial", "--at", 1), e.value, e.allowed, e.reason) from None
    else:
        state = given
    return system, variant, state, params


def _accelerations(args: argparse.Namespace) -> int:
    from ..analysis.at_state import accelerations

    system, variant, state, params = _state(args)
    acc = accelerations(system, state, params, variant)
    if args.json:
        print(json.dumps(acc, indent=2))
    else:
        for k, v in acc.items():
            print(f"d{k}/dt = {v:.12g}")
    return 0


def _add_linearize(p: argparse.ArgumentParser) -> None:
    _common(p)
    p.add_argument(
        "--keep",
        action="append",
        default=None,
        metavar="NAME",
        help="an independent coordinate or speed to keep in the linearized state (repeatable; "
        "default: all independent ones)",
    )
    p.add_argument("--step", type=finite, default=1e-3, help="relative perturbation of the differences")


def _linearize(args: argparse.Namespace) -> int:
    from ..analysis.at_state import linearize

    system, variant, state, params = _state(args)
    lin = linearize(system, state, params, variant, keep=args.keep, step=args.step)
    if args.json:
        print(json.dumps(lin.as_dict(), indent=2))
        return 0
    width = max(len(n) for n in lin.names)
    print("state matrix A (rows: d/dt of, columns: per unit of)")
    print(" " * (width + 2) + " ".join(f"{n:>14}" for n in lin.names))
    for name, row in zip(lin.names, lin.A, strict=True):
        print(f"{name:>{width}}  " + " ".join(f"{v:14.8g}" for v in row))
    print("eigenvalues")
    for ev in sorted(lin.eigenvalues, key=lambda v: (v.real, v.imag)):
        print(f"  {ev.real:+.12g} {ev.imag:+.12g}i")
    return 0


ACCELERATIONS = Command("accelerations", "du/dt of every speed at a full consistent state", _common, _accelerations)
LINEARIZE = Command(
    "linearize",
    "the linearized equations of the independent coordinates and speeds about a state, with eigenvalues",
    _add_linearize,
    _linearize,
)
