"""The ``nmkane`` command: run, serve, bench, figures, matrices.

Errors in options or input print one line naming the option, the value and what is
allowed, and exit with code 2 (no traceback).  ``nmkane run`` exits 0 when the run's
status is ``ok`` and 1 when it ended ``singular``, ``diverged``, ``timeout`` or
``failed`` (its output file is written either way).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import sys
import threading
import time

from .errors import InputError, NmkaneError

PROG = "nmkane"

_FIELD_TO_OPTION = {"t_final": "--t-final", "dt": "--dt", "every": "--every", "gamma": "--gamma",
                    "gamma1": "--gamma1", "gamma2": "--gamma2", "integrator": "--integrator",
                    "model": "--model", "formulation": "--formulation", "projection": "--projection",
                    "rtol": "--rtol", "atol": "--atol", "rcond_min": "--rcond-min", "out": "--out",
                    "rcond_switch": "--rcond-switch",
                    "system": "SYSTEM", "initial": "--init"}


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        self.exit(2, f"{self.prog}: error: {message}\n")


def _finite(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def _positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def _assignment(text: str) -> tuple[str, float]:
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), _finite(value)


def _option_for(field: str) -> str:
    if field.startswith("params."):
        return f"--set {field.split('.', 1)[1]}"
    if field.startswith("initial."):
        return f"--init {field.split('.', 1)[1]}"
    return _FIELD_TO_OPTION.get(field, field)


def _input_error_line(err: InputError) -> str:
    text = f"{_option_for(err.field)}: got {err.value!r}"
    if err.reason:
        text += f" ({err.reason})"
    return f"{text}; allowed: {err.allowed}"


def _build_parser() -> argparse.ArgumentParser:
    from .integrators import integrator_names

    parser = _Parser(prog=PROG, description="Nonminimal Kane's equations (Bajodah, Hodges & Chen 2005): "
                     "simulate, serve the REST API and 3D web app, benchmark, reproduce the paper.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="simulate a system and print a summary or write a file")
    run.add_argument("system", metavar="SYSTEM", help="appell-hamel | sliding-particle")
    run.add_argument("--model", help="appell-hamel constraint model: nonlinear | linear")
    run.add_argument("--formulation", help="sliding-particle: nonminimal | minimal")
    run.add_argument("--gamma", type=_finite, help="Γ (nonholonomic), applied as Γ·I; stabilizing < 0")
    run.add_argument("--gamma1", type=_finite, help="Γ1 (holonomic, s⁻¹), e.g. -20")
    run.add_argument("--gamma2", type=_finite, help="Γ2 (holonomic, s⁻²), e.g. -100")
    run.add_argument("--projection", default="none", help="post-step correction: none | blajer | yoon")
    run.add_argument("--projection-weight", dest="projection_weight", choices=("identity", "mass"),
                     help="override the projection's weighting matrix W")
    run.add_argument("--projection-iterations", dest="projection_iterations", type=_positive_int,
                     help="override the Newton iterations of the position correction (1 = one-shot)")
    run.add_argument("--projection-jacobian", dest="projection_jacobian", choices=("updated", "frozen"),
                     help="override: position Jacobian updated each iteration or frozen")
    run.add_argument("--projection-energy", dest="projection_energy", choices=("yes", "no"),
                     help="override: restore the initial energy after each correction")
    run.add_argument("--integrator", choices=integrator_names(), metavar="NAME",
                     help=" | ".join(integrator_names()))
    run.add_argument("--dt", type=_finite, help="step size in s (initial step for adaptive methods)")
    run.add_argument("--t-final", type=_finite, dest="t_final", help="final time in s")
    run.add_argument("--every", type=_positive_int, default=1, help="keep every k-th step in the output")
    run.add_argument("--rtol", type=_finite, help="relative tolerance (adaptive methods, default 1e-10)")
    run.add_argument("--atol", type=_finite, help="absolute tolerance (adaptive methods, default 1e-12)")
    run.add_argument("--rcond-min", type=_finite, dest="rcond_min",
                     help="stop as singular below this reciprocal condition of J2 or T (default 1e-10)")
    run.add_argument("--no-switching", action="store_true",
                     help="stop as singular instead of switching to an equivalent constraint model")
    run.add_argument("--rcond-switch", type=_finite, dest="rcond_switch",
                     help="reciprocal condition at which to switch models (default 1e-2)")
    run.add_argument("--project-initial", action="store_true",
                     help="project an inconsistent full initial state onto the constraints (reported)")
    run.add_argument("--set", type=_assignment, action="append", default=[], metavar="NAME=VALUE",
                     help="a physical parameter, e.g. --set rho=4")
    run.add_argument("--init", type=_assignment, action="append", default=[], metavar="NAME=VALUE",
                     help="an initial value: independent ones (the rest is completed) or a full state")
    run.add_argument("--out", help="write FILE.json (run document), FILE.csv or FILE.npz")
    run.add_argument("--time-limit", type=_finite, dest="time_limit", help="wall-time limit in s")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")

    serve = sub.add_parser("serve", help="start the REST service and the 3D web app")
    serve.add_argument("--host", default="127.0.0.1")
    serve.add_argument("--api-port", type=int, default=8000)
    serve.add_argument("--viser-port", type=int, default=8080)
    serve.add_argument("--no-web", action="store_true", help="REST service only")

    bench = sub.add_parser("bench", help="measure the kernels' speed and print a table")
    bench.add_argument("--json", action="store_true", help="machine-readable output")
    bench.add_argument("--quick", action="store_true", help="shorter workloads (smoke test)")

    figs = sub.add_parser("figures", help="regenerate the paper's figures and the claims report")
    figs.add_argument("--out", default="figures", help="output directory (default ./figures)")
    figs.add_argument("--quick", action="store_true", help="shorter horizons where the claim allows")

    mats = sub.add_parser("matrices", help="print the derived matrices (LaTeX or text)")
    mats.add_argument("system", metavar="SYSTEM")
    mats.add_argument("--model")
    mats.add_argument("--formulation")
    mats.add_argument("--matrix", action="append", default=[], help="J1 J2 A B A1 A2 Q P T V B_hat V_hat")
    mats.add_argument("--latex", action="store_true", help="LaTeX instead of text")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = _build_parser()
    args = parser.parse_args(argv)
    try:
        if args.command == "run":
            return _cmd_run(args)
        if args.command == "serve":
            from backend.serve import serve

            serve(host=args.host, api_port=args.api_port, viser_port=args.viser_port, web=not args.no_web)
            return 0
        if args.command == "bench":
            from .bench import main as bench_main

            return bench_main(json_out=args.json, quick=args.quick)
        if args.command == "figures":
            from .figures import make_figures

            report = make_figures(args.out, progress=None, quick=args.quick)
            print(report.summary_text() if hasattr(report, "summary_text") else report)
            return 0
        if args.command == "matrices":
            return _cmd_matrices(args)
    except InputError as e:
        print(f"{PROG} {args.command}: error: {_input_error_line(e)}", file=sys.stderr)
        return 2
    except NmkaneError as e:
        print(f"{PROG} {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:      # output piped into `head` and closed: not an error of ours
        sys.stderr.close()
        return 0
    return 0


def _settings_from_args(args) -> dict:
    settings = {"system": args.system, "every": args.every, "projection": args.projection,
                "params": dict(args.set), "initial": dict(args.init),
                "switching": not args.no_switching, "project_initial": args.project_initial}
    if args.projection_energy is not None:
        settings["projection_energy"] = args.projection_energy == "yes"
    for key in ("model", "formulation", "gamma", "gamma1", "gamma2", "integrator", "dt", "t_final",
                "rtol", "atol", "rcond_min", "rcond_switch", "projection_weight", "projection_iterations",
                "projection_jacobian"):
        v = getattr(args, key)
        if v is not None:
            settings[key] = v
    return settings


def _validated(settings: dict):
    from .plan import validate_settings

    return validate_settings(settings)


@contextlib.contextmanager
def notice_if_slow(message: str, enabled: bool = True, after: float = 1.0, stream=None):
    """Say ``message`` on stderr if the block is still running after ``after`` seconds, and
    how long it took when it ends (a first use derives and compiles: seconds of silence
    otherwise).  Quick blocks print nothing."""
    stream = stream if stream is not None else sys.stderr
    said = threading.Event()

    def say():
        said.set()
        print(f"{PROG}: {message} …", file=stream, flush=True)

    timer = threading.Timer(after, say) if enabled else None
    t0 = time.perf_counter()
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        yield
    finally:
        if timer is not None:
            timer.cancel()
        if said.is_set():
            print(f"{PROG}: ready in {time.perf_counter() - t0:.1f} s (cached for later runs)", file=stream,
                  flush=True)


def _cmd_run(args) -> int:
    from .drivers import prepare
    from .plan import resolve
    from .simulate import simulate

    if args.out and not args.out.endswith((".json", ".csv", ".npz")):
        raise InputError("out", args.out, "a file name ending in .json, .csv or .npz", "unknown format")
    settings = _validated(_settings_from_args(args))
    progress = False if args.no_progress else None
    with notice_if_slow(f"preparing {args.system} (a first use derives the equations and compiles them)",
                        enabled=not args.no_progress and sys.stderr.isatty()):
        plan = resolve(settings)
        prepare(plan)
    run = simulate(plan, progress=progress, time_limit=args.time_limit)
    if args.out:
        run.save(args.out)
        print(f"{run.status}: {run.summary['message']} -> {args.out}")
    else:
        print(format_summary(run))
    return 0 if run.status == "ok" else 1


def format_summary(run) -> str:
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
    if s.get("switches"):
        for sw in s["switches"]:
            lines.append(f"switch   t = {sw['t']:.4g} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.2g})")
    for w in s.get("warnings", []):
        lines.append(f"warning  {w}")
    final = ", ".join(f"{k} = {v[-1]:.6g}" for k, v in run.state.items())
    lines.append(f"final    t = {run.t[-1]:.6g} s: {final}")
    return "\n".join(lines)


def _cmd_matrices(args) -> int:
    import sympy as sp

    from .system import get_system

    system = get_system(args.system)
    other = "formulation" if system.option == "model" else "model"
    if getattr(args, other):
        raise InputError(other, getattr(args, other), f"{system.option}: {' | '.join(system.variants)}",
                         f"{system.name} has no {other}")
    variant = system.check_variant(getattr(args, system.option), system.option)
    d = system.derivation(variant)
    names = args.matrix or ["J1", "J2", "A1", "A2", "T"]
    for name in names:
        if name not in d.NAMES:
            raise InputError("--matrix", name, " | ".join(d.NAMES), "unknown matrix")
        if args.latex:
            print(d.latex(name))
        else:
            mat = d.matrix(name).applyfunc(lambda e: sp.simplify(e) if sp.count_ops(e) < 300 else e)
            print(f"{name} =")
            print(sp.pretty(mat, use_unicode=True, wrap_line=False))
        print()
    return 0


def entry() -> None:
    """The ``nmkane`` console command: :func:`main`, then a quick exit.

    Tearing the interpreter down after numba has loaded machine code (freeing its LLVM
    modules one by one) takes about 0.5 s — a quarter of a cached ``nmkane run`` — and does
    nothing a finished command needs: files are closed by then, so the output streams are
    flushed and the process ends with ``os._exit``.  ``serve`` (threads, servers) and
    errors escaping ``main`` take the ordinary exit.
    """
    args = sys.argv[1:]
    try:
        code = main(args)
    except SystemExit as e:                 # argparse: --help, usage errors
        code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
        if isinstance(e.code, str):
            print(e.code, file=sys.stderr)
    if args[:1] == ["serve"]:
        sys.exit(code)
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (BrokenPipeError, ValueError):   # a closed pipe or stream: nothing left to flush
        pass
    os._exit(code)


if __name__ == "__main__":
    entry()
