"""``nmkane bench``: the speed table (see :mod:`nmkane_core.bench.rows`)."""

from __future__ import annotations

import argparse

from .command import Command


def _add_arguments(bench: argparse.ArgumentParser) -> None:
    bench.add_argument("--json", action="store_true", help="machine-readable output")
    bench.add_argument("--quick", action="store_true", help="shorter workloads (smoke test)")
    bench.add_argument("--long", action="store_true", help="the slow rows too (a 10,000-run sweep's memory)")
    bench.add_argument("--strict", action="store_true", help="exit with status 1 when a row misses its target")


def _run(args: argparse.Namespace) -> int:
    from ..bench.rows import main as bench_main

    return bench_main(json_out=args.json, quick=args.quick, strict=args.strict, long=args.long)


COMMAND = Command("bench", "measure the kernels' speed and print a table", _add_arguments, _run)
