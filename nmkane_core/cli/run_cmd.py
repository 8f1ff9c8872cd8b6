"""``nmkane run SYSTEM [options]``: one simulation, a readable summary or a file.

Exit code 0 when the run's status is ``ok``, 1 when it ended ``singular``, ``diverged``,
``timeout`` or ``failed`` (its output file is written either way), 2 on bad input.
"""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from .command import Command
from .common import add_systems_option, assignment, finite, load_plugged_systems, notice_if_slow, positive_int


def add_run_options(run: argparse.ArgumentParser) -> None:
    """The run settings as options (shared by every command that runs a system)."""
    from ..integrate.methods import integrator_names

    run.add_argument("system", metavar="SYSTEM", help="a registered system, e.g. appell-hamel")
    add_systems_option(run)
    run.add_argument("--model", help="the system's constraint model (systems whose variants are models)")
    run.add_argument("--formulation", help="the system's formulation (systems whose variants are formulations)")
    run.add_argument("--gamma", type=finite, help="Γ (nonholonomic), applied as Γ·I; stabilizing < 0")
    run.add_argument("--gamma1", type=finite, help="Γ1 (holonomic, s⁻¹), e.g. -20")
    run.add_argument("--gamma2", type=finite, help="Γ2 (holonomic, s⁻²), e.g. -100")
    run.add_argument("--projection", default="none", help="post-step correction: none | blajer | yoon")
    run.add_argument(
        "--projection-weight",
        dest="projection_weight",
        choices=("identity", "mass"),
        help="override the projection's weighting matrix W",
    )
    run.add_argument(
        "--projection-iterations",
        dest="projection_iterations",
        type=positive_int,
        help="override the Newton iterations of the position correction (1 = one-shot)",
    )
    run.add_argument(
        "--projection-jacobian",
        dest="projection_jacobian",
        choices=("updated", "frozen"),
        help="override: position Jacobian updated each iteration or frozen",
    )
    run.add_argument(
        "--projection-energy",
        dest="projection_energy",
        choices=("yes", "no"),
        help="override: restore the initial energy after each correction",
    )
    run.add_argument("--integrator", choices=integrator_names(), metavar="NAME", help=" | ".join(integrator_names()))
    run.add_argument("--dt", type=finite, help="step size in s (initial step for adaptive methods)")
    run.add_argument("--t-final", type=finite, dest="t_final", help="final time in s")
    run.add_argument("--every", type=positive_int, default=1, help="keep every k-th step in the output")
    run.add_argument("--rtol", type=finite, help="relative tolerance (adaptive methods, default 1e-10)")
    run.add_argument("--atol", type=finite, help="absolute tolerance (adaptive methods, default 1e-12)")
    run.add_argument(
        "--rcond-min",
        type=finite,
        dest="rcond_min",
        help="stop as singular below this reciprocal condition of J2 or T (default 1e-10)",
    )
    run.add_argument(
        "--no-switching",
        action="store_true",
        help="stop as singular instead of switching to an equivalent constraint model",
    )
    run.add_argument(
        "--rcond-switch",
        type=finite,
        dest="rcond_switch",
        help="reciprocal condition at which to switch models (default 1e-2)",
    )
    run.add_argument(
        "--project-initial",
        action="store_true",
        help="project an inconsistent full initial state onto the constraints (reported)",
    )
    run.add_argument(
        "--set",
        type=assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a physical parameter, e.g. --set rho=4",
    )
    run.add_argument(
        "--init",
        type=assignment,
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="an initial value: independent ones (the rest is completed) or a full state",
    )


def _add_arguments(run: argparse.ArgumentParser) -> None:
    add_run_options(run)
    run.add_argument("--out", help="write FILE.json (run document), FILE.csv or FILE.npz")
    run.add_argument("--time-limit", type=finite, dest="time_limit", help="wall-time limit in s")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")


def settings_from_args(args: argparse.Namespace) -> dict:
    """The run settings (as the REST API takes them) from parsed run options."""
    settings = {
        "system": args.system,
        "every": args.every,
        "projection": args.projection,
        "params": dict(args.set),
        "initial": dict(args.init),
        "switching": not args.no_switching,
        "project_initial": args.project_initial,
    }
    if args.projection_energy is not None:
        settings["projection_energy"] = args.projection_energy == "yes"
    for key in (
        "model",
        "formulation",
        "gamma",
        "gamma1",
        "gamma2",
        "integrator",
        "dt",
        "t_final",
        "rtol",
        "atol",
        "rcond_min",
        "rcond_switch",
        "projection_weight",
        "projection_iterations",
        "projection_jacobian",
    ):
        v = getattr(args, key)
        if v is not None:
            settings[key] = v
    return settings


def _run(args: argparse.Namespace) -> int:
    from ..integrate.drivers import prepare
    from ..run.plan import resolve, validate_settings
    from ..run.simulate import simulate

    if args.out and not args.out.endswith((".json", ".csv", ".npz")):
        raise InputError("out", args.out, "a file name ending in .json, .csv or .npz", "unknown format")
    load_plugged_systems(args)
    settings = validate_settings(settings_from_args(args))
    progress = False if args.no_progress else None
    with notice_if_slow(
        f"preparing {args.system} (a first use derives the equations and compiles them)",
        enabled=not args.no_progress and sys.stderr.isatty(),
    ):
        plan = resolve(settings)
        prepare(plan)
    run = simulate(plan, progress=progress, time_limit=args.time_limit)
    if args.out:
        run.save(args.out)
        print(f"{run.status}: {run.summary['message']} -> {args.out}")
    else:
        print(format_summary(run))
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
    viol = ", ".join(f"{k} {v:.3e}" for k, v in s["max_abs_violation"].items())
    lines.append(f"max |φ|  {viol}")
    for sw in s.get("switches") or []:
        lines.append(f"switch   t = {sw['t']:.4g} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.2g})")
    for w in s.get("warnings", []):
        lines.append(f"warning  {w}")
    final = ", ".join(f"{k} = {v[-1]:.6g}" for k, v in run.state.items())
    lines.append(f"final    t = {run.t[-1]:.6g} s: {final}")
    return "\n".join(lines)


COMMAND = Command("run", "simulate a system and print a summary or write a file", _add_arguments, _run)
