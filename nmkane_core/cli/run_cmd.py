"""``nmkane run SYSTEM [options]``: one simulation, a readable summary or a file.

Exit code 0 when the run's status is ``ok`` (or ``event``), 1 when it ended ``singular``,
``diverged``, ``drifted``, ``timeout`` or ``failed`` (its output file is written either way), 2 on
bad input.
``--plot Y[:X]`` also draws the run's quantities to a PNG (:mod:`.plot_out`).
"""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from .argtypes import finite
from .command import Command
from .common import check_writable, load_plugged_systems, notice_if_slow
from .plot_out import check_plot_out, plot_file, split_plot, write_plots
from .run_options import add_run_options, settings_from_args


def add_simulation_arguments(parser: argparse.ArgumentParser) -> None:
    """What every command that runs one simulation takes: the run options, a wall-time
    limit and ``--no-progress`` (``nmkane run``, ``nmkane export``)."""
    add_run_options(parser)
    parser.add_argument("--time-limit", type=finite, dest="time_limit", help="wall-time limit in s")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def simulate_from_args(args: argparse.Namespace):
    """The run the options of :func:`add_simulation_arguments` ask for (plugged-in systems
    loaded, settings checked, a first use announced on a terminal)."""
    from ..run.plan import resolve, validate_settings
    from ..run.simulate import prepare, simulate

    load_plugged_systems(args)
    settings = validate_settings(settings_from_args(args))
    progress = False if args.no_progress else None
    with notice_if_slow(
        f"preparing {args.system} (a first use derives the equations and compiles them)",
        enabled=not args.no_progress and sys.stderr.isatty(),
    ):
        plan = resolve(settings)
        prepare(plan)
    return simulate(plan, progress=progress, time_limit=args.time_limit)


def _add_arguments(run: argparse.ArgumentParser) -> None:
    add_simulation_arguments(run)
    run.add_argument("--out", help="write FILE.json (run document), FILE.csv or FILE.npz")
    run.add_argument(
        "--plot",
        action="append",
        default=[],
        metavar="Y[:X]",
        help="draw Y against t, or Y:X (Y against X), to a PNG; Y and X are expressions of the run's quantities "
        "(t, coordinates, speeds, E, dE, phi_<constraint>, F_<speed>, lambda_<constraint>, R_<force>_<label>), "
        "e.g. --plot phi_c1 --plot u2:u1; repeat for more panels",
    )
    run.add_argument("--plot-out", dest="plot_out", metavar="FILE.png", help="where --plot draws (<system>-plot.png)")


def _run(args: argparse.Namespace) -> int:
    if args.out and not args.out.endswith((".json", ".csv", ".npz")):
        raise InputError("out", args.out, "a file name ending in .json, .csv or .npz", "unknown format")
    if args.out:
        check_writable("out", args.out)
    check_plot_out(args.plot_out)
    if args.plot:
        check_writable("plot_out", plot_file(args.system, args.plot_out))
    for text in args.plot:
        split_plot(text)
    run = simulate_from_args(args)
    if args.out:
        run.save(args.out)
        print(f"{run.status}: {run.summary['message']} -> {args.out}")
    else:
        print(format_summary(run))
    if args.plot:
        print(f"plot -> {write_plots(run, args.plot, plot_file(args.system, args.plot_out))}")
    return 0 if run.status in ("ok", "event") else 1  # an event is a clean stop, not a failure


def format_summary(run) -> str:
    """A run's summary as the terminal shows it."""
    s, st = run.summary, run.settings
    variant_key = "model" if st.get("model") else "formulation"
    lines = [
        f"{run.system} ({variant_key} {st.get(variant_key)}), {st['integrator']}, dt = {st['dt']:g} s, "
        f"t = 0 … {st['t_final']:g} s",
        f"status   {s['status']}: {s['message']}",
        f"work     {s['steps']:,} steps, {s['rhs_evals']:,} right-hand-side evaluations, "
        f"{s['wall_time_s']:.3f} s wall time",
    ]
    if s["max_abs_energy_drift"] is not None:
        lines.append(f"energy   max |ΔE| = {s['max_abs_energy_drift']:.3e}, final ΔE = {s['final_energy_drift']:.3e}")
    lines.append(f"max |φ|  {_largest(s['max_abs_violation'])}")
    if s.get("max_abs_multiplier"):
        lines.append(f"max |λ|  {_largest(s['max_abs_multiplier'])}  (constraint forces F_c = Jᵀλ)")
    if s.get("max_abs_point_force"):
        at = ", ".join(f"{k} {v:.4g} N" for k, v in s["max_abs_point_force"].items())
        lines.append(f"max |F|  {at}  (forces at points: {', '.join(run.point_forces)})")
    if (part := s.get("partition")) and run.violation:  # a constrained model: which speeds are independent
        how = "declared" if part["chosen"] == "declared" else "picked by pivoting at the default state"
        solved = f"; q solved: {', '.join(part['q_dependent'])}" if part["q_dependent"] else ""
        lines.append(f"partition u_I: {', '.join(part['u_independent'])}{solved} ({how})")
    for sw in s.get("switches") or []:
        lines.append(f"switch   t = {sw['t']:.4g} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.2g})")
    if crossings := s.get("crossings"):
        listed = ", ".join(f"{c['name']} {c['direction']} at {c['t']:.6g} s" for c in crossings[:MOST])
        more = len(crossings) - MOST + s.get("crossings_not_listed", 0)
        lines.append(f"events   {listed}" + (f", … ({more} more; --out FILE.json lists them)" if more > 0 else ""))
    if est := s.get("error_estimate"):  # --error-estimate: the run against a refined one
        lines.append(f"error    {_error_estimate(est)}")
    for w in s.get("warnings", []):
        lines.append(f"warning  {w}")
    final = [f"{k} = {v[-1]:.6g}" for k, v in run.state.items()]
    more = f", … ({len(final)} values; --out FILE.json has them all)" if len(final) > 2 * MOST else ""
    lines.append(f"final    t = {run.t[-1]:.6g} s: {', '.join(final[: 2 * MOST] if more else final)}{more}")
    return "\n".join(lines)


def _error_estimate(est: dict) -> str:
    """The summary's ``error_estimate`` on one line: the estimated global error of each state, or
    why there is none."""
    if est["max_abs"] is None:
        return est["message"]
    refined = ", ".join(f"{k} = {v:g}" + (" s" if k == "dt" else "") for k, v in est["refined"].items() if k != "every")
    how = f"estimated global error, from a run at {refined}"
    if est["richardson"]:
        p = est["order"]
        return f"{_largest(est['richardson'])}  ({how}; Richardson ×{2**p}/{2**p - 1})"
    return f"{_largest(est['max_abs'])}  ({how})"


MOST = 8  # entries of a summary line; a large model's lines show the largest (a chain: 80 constraints)


def _largest(values: dict) -> str:
    """``name value`` of each entry, or of the MOST largest and how many more there are."""
    if len(values) <= MOST:
        return ", ".join(f"{k} {v:.3e}" for k, v in values.items())
    top = sorted(values.items(), key=lambda kv: -abs(kv[1]))[:MOST]
    return ", ".join(f"{k} {v:.3e}" for k, v in top) + f", … ({len(values) - MOST} more, each smaller)"


COMMAND = Command("run", "simulate a system and print a summary or write a file", _add_arguments, _run)
