"""``nmkane matrices SYSTEM``: the partition and why (declared, or the pivots of the elimination that
picked it, and J2's condition estimate at the default state), then the derived matrices of the
paper's procedure, as text or LaTeX."""

from __future__ import annotations

import argparse

from ..errors import InputError, NotDefined
from .argtypes import add_systems_option
from .command import Command
from .common import load_plugged_systems


def _add_arguments(mats: argparse.ArgumentParser) -> None:
    mats.add_argument("system", metavar="SYSTEM")
    add_systems_option(mats)
    mats.add_argument("--model")
    mats.add_argument("--formulation")
    mats.add_argument("--matrix", action="append", default=[], help="J1 J2 A B A1 A2 Q P T V B_hat V_hat")
    mats.add_argument("--latex", action="store_true", help="LaTeX instead of text")
    mats.add_argument(
        "--width",
        type=int,
        default=None,
        help="text columns: a matrix wider than this is printed entry by entry (default: the terminal's)",
    )


def _run(args: argparse.Namespace) -> int:

    from ..kernel.built import built
    from ..run.registry import get_system
    from ..symbolic.shorten import Budget

    load_plugged_systems(args)
    system = get_system(args.system)
    other = "formulation" if system.option == "model" else "model"
    if getattr(args, other):
        raise InputError(
            other,
            getattr(args, other),
            f"{system.option}: {' | '.join(system.variants)}",
            f"{system.name} has no {other}",
        )
    variant = system.check_variant(getattr(args, system.option), system.option)
    from ..run.initial import default_state
    from ..run.partition import explain_partition

    for line in explain_partition(system, variant, default_state(system)):
        print(line)
    print()
    d = built(system).derivation(variant)
    names = args.matrix or ["J1", "J2", "A1", "A2", "T"]
    for name in names:
        if name not in d.NAMES:
            raise InputError("--matrix", name, " | ".join(d.NAMES), "unknown matrix")
    budget = Budget()  # sympy's simplify takes seconds an entry on a closed loop's matrices
    for name in names:
        if not args.matrix:  # the default set: what the model does not have is said, not raised
            try:
                d.matrix(name)
            except NotDefined as e:
                print(f"{name}: not defined. {e}")
                print()
                break
        if args.latex:
            print(d.latex(name))
        else:
            _print_text(name, d.matrix(name).applyfunc(budget.simplified), args.width)
        print()
    return 0


def _print_text(name: str, mat, width: int | None) -> None:
    """A matrix as text: one block where it fits ``width`` columns, else entry by entry (its
    nonzero entries, each typeset on its own, wrapped at ``width``) — a class reads Example 1's
    T (a 246-column block) that way."""
    import shutil

    import sympy as sp

    width = max(40, width if width is not None else shutil.get_terminal_size((100, 24)).columns)
    block = sp.pretty(mat, use_unicode=True, wrap_line=False)
    if max((len(line) for line in block.splitlines()), default=0) <= width:
        print(f"{name} =")
        print(block)
        return
    zeros = sum(1 for e in mat if e == 0)
    print(
        f"{name}: {mat.rows}×{mat.cols}, wider than {width} columns as a block: entry by entry ({zeros} zeros left out)"
    )
    for i in range(mat.rows):
        for j in range(mat.cols):
            if mat[i, j] != 0:
                print(f"{name}[{i + 1},{j + 1}] =")
                print(sp.pretty(mat[i, j], use_unicode=True, num_columns=width))


COMMAND = Command(
    "matrices",
    "print the partition and why (the pivots that picked it, J2's estimate), then the derived matrices (LaTeX or text)",
    _add_arguments,
    _run,
)
