"""``nmkane sweep SYSTEM [run options] --grid/--log-grid/--sample ... --out FILE``: many runs
over settings fields, parameters and initial values, on local cores or a Dask cluster.

Exit code 0 when every run ended ``ok``, 1 when some did not (the output has them all),
2 on a bad specification (one line naming the option, the value and what is allowed).
"""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from .argtypes import finite, positive_int
from .command import Command
from .common import check_writable, load_plugged_systems
from .run_options import add_run_options, settings_from_args


def add_sweep_options(p: argparse.ArgumentParser) -> None:
    """Where a sweep runs and how (shared with ``nmkane tune``)."""
    p.add_argument(
        "--workers", type=positive_int, help="local worker processes (default: all cores; 1 = in this process)"
    )
    p.add_argument(
        "--dask",
        metavar="WHERE",
        help="run on Dask: local | local:N (a LocalCluster of N worker "
        "processes) | tcp://HOST:PORT (a running scheduler; its workers need nmkane installed)",
    )
    p.add_argument("--time-limit", type=finite, dest="time_limit", help="wall-time limit per run, s")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_arguments(p: argparse.ArgumentParser) -> None:
    add_run_options(p)
    p.add_argument(
        "--grid",
        action="append",
        default=[],
        metavar="NAME=START:STOP:NUM|NAME=V1,V2,...",
        help="vary NAME over NUM evenly spaced values (both ends included) or a list; NAME is a "
        "settings field (gamma, gamma1, gamma2, dt, t_final, integrator, ...), params.NAME or "
        "initial.NAME (repeatable: a Cartesian product)",
    )
    p.add_argument(
        "--log-grid",
        dest="log_grid",
        action="append",
        default=[],
        metavar="NAME=START:STOP:NUM",
        help="NUM log-spaced values from START to STOP (one sign, e.g. gamma=-0.1:-1000:9)",
    )
    p.add_argument(
        "--sample",
        action="append",
        default=[],
        metavar="NAME=LOW:HIGH",
        help="a Latin-hypercube dimension (with --samples N)",
    )
    p.add_argument("--samples", type=positive_int, help="Latin-hypercube points")
    p.add_argument(
        "--seed",
        type=int,
        default=0,
        help="Latin-hypercube seed, an integer in [0, 2**32 - 1] (default 0; resuming needs the same)",
    )
    p.add_argument("--out", required=True, help="FILE.csv or FILE.parquet (pyarrow); an existing file is resumed")
    p.add_argument("--restart", action="store_true", help="start --out anew instead of resuming it")
    p.add_argument("--plot", metavar="FILE.png", help="draw --metric over the varied names (one: lines, two: heatmap)")
    p.add_argument(
        "--metric",
        default="log10_max_violation",
        help="what --plot draws: a column, max_violation, or log10_ before either (default log10_max_violation)",
    )
    add_sweep_options(p)


def _run(args: argparse.Namespace) -> int:
    from ..run.plan import validate_settings
    from ..sweep import read_rows, run_sweep, sweep_spec
    from ..sweep.output import check_out

    check_out(args.out)
    check_writable("out", args.out)
    if args.plot and not args.plot.endswith((".png", ".svg", ".pdf")):
        raise InputError("--plot", args.plot, "a file name ending in .png, .svg or .pdf", "unknown format")
    if args.plot:
        check_writable("plot", args.plot)
    spec = sweep_spec(args.grid, args.log_grid, args.sample, args.samples, args.seed)
    if args.plot and len(spec.names) not in (1, 2):
        raise InputError(
            "--plot", args.plot, "a sweep of one varied name (lines) or two (heatmap)", f"{len(spec.names)} names vary"
        )
    load_plugged_systems(args)
    base = validate_settings(settings_from_args(args)).model_dump(exclude_none=True)
    progress = False if args.no_progress else None
    res = run_sweep(
        base,
        spec,
        args.out,
        systems=tuple(args.systems),
        dask=args.dask,
        workers=args.workers,
        progress=progress,
        time_limit=args.time_limit,
        resume=not args.restart,
    )
    statuses = ", ".join(f"{k} {v}" for k, v in sorted(res.statuses.items())) or "nothing new"
    rate = f", {res.ran / res.wall_s:.1f} runs/s" if res.ran and res.wall_s > 0 else ""
    print(
        f"{res.total} runs ({res.skipped} already in {args.out}): {statuses}; {res.executor} × {res.workers}"
        f"{rate} -> {args.out}"
    )
    if args.plot:
        from ..sweep.plot import plot_sweep

        columns, rows = read_rows(args.out)
        plot_sweep(rows, columns, spec.names, args.plot, args.metric, title=f"{args.system}: {args.metric}")
        print(f"plot -> {args.plot}", file=sys.stderr)
    bad = sum(v for k, v in res.statuses.items() if k != "ok")
    return 0 if bad == 0 else 1


COMMAND = Command(
    "sweep", "many runs over gains, parameters and initial values (local cores or Dask)", _add_arguments, _run
)
