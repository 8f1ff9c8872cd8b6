"""What every ``nmkane`` subcommand shares: the one-line error parser, argument types,
how an :class:`~nmkane_core.errors.InputError` is printed, and the "first use" notice."""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import threading
import time

from ..errors import InputError

PROG = "nmkane"

# settings field -> the option a user typed (errors name what the user wrote)
FIELD_TO_OPTION = {
    "t_final": "--t-final",
    "dt": "--dt",
    "every": "--every",
    "gamma": "--gamma",
    "gamma1": "--gamma1",
    "gamma2": "--gamma2",
    "integrator": "--integrator",
    "model": "--model",
    "formulation": "--formulation",
    "projection": "--projection",
    "rtol": "--rtol",
    "atol": "--atol",
    "rcond_min": "--rcond-min",
    "out": "--out",
    "rcond_switch": "--rcond-switch",
    "system": "SYSTEM",
    "initial": "--init",
}


class Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors and exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def finite(text: str) -> float:
    """argparse type: a finite float."""
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return v


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1."""
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return v


def assignment(text: str) -> tuple[str, float]:
    """argparse type: NAME=VALUE with a finite value."""
    name, sep, value = text.partition("=")
    if not sep or not name:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), finite(value)


def option_for(field: str) -> str:
    """The command-line spelling of a settings field (``params.rho`` -> ``--set rho``)."""
    if field.startswith("params."):
        return f"--set {field.split('.', 1)[1]}"
    if field.startswith("initial."):
        return f"--init {field.split('.', 1)[1]}"
    return FIELD_TO_OPTION.get(field, field)


def input_error_line(err: InputError) -> str:
    text = f"{option_for(err.field)}: got {err.value!r}"
    if err.reason:
        text += f" ({err.reason})"
    return f"{text}; allowed: {err.allowed}"


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
            print(f"{PROG}: ready in {time.perf_counter() - t0:.1f} s (cached for later runs)", file=stream, flush=True)


def add_systems_option(p: argparse.ArgumentParser) -> None:
    """``--systems PATH_OR_MODULE`` (repeatable): plug-in systems to load first."""
    p.add_argument(
        "--systems",
        action="append",
        default=[],
        metavar="PATH_OR_MODULE",
        help="a systems file (.py) or module to load first (repeatable; runs as Python code); "
        "also $NMKANE_SYSTEMS and the nmkane.systems entry points",
    )


def load_plugged_systems(args: argparse.Namespace, strict: bool = True) -> None:
    """Load the ``--systems`` of a command (strict: the first failure is the command's error)."""
    from ..run.plugins import load_systems

    for err in load_systems(getattr(args, "systems", []) or [], strict=strict):
        print(err, file=sys.stderr)
