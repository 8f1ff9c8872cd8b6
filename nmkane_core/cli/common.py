"""What every ``nmkane`` subcommand shares: the one-line error parser, argument types,
how an :class:`~nmkane_core.errors.InputError` is printed, and the "first use" notice."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import threading
import time
from pathlib import Path

from ..errors import InputError
from .run_options import option_of

PROG = "nmkane"


class Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors and exit code 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def input_error_line(err: InputError) -> str:
    """An error as one line naming the option the user typed (``--dt``, ``--set rho``)."""
    text = f"{option_of(err.field)}: got {err.value!r}"
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


def load_plugged_systems(args: argparse.Namespace, strict: bool = True) -> None:
    """Load the ``--systems`` of a command (strict: the first failure is the command's error)."""
    from ..run.plugins import load_systems

    for err in load_systems(getattr(args, "systems", []) or [], strict=strict):
        print(err, file=sys.stderr)


def check_writable(field: str, path: str) -> None:
    """Refuse, before any work, an output file that could not be written: in a folder that does
    not exist or that this user may not write, the name of a folder, or a file not writable
    (an :class:`InputError` naming ``field``, the path and why)."""
    p = Path(path)
    folder = p.parent  # Path("r.json").parent is Path("."), the working folder
    if not folder.is_dir():
        why = f"{folder} is not a folder" if folder.exists() else f"no folder {folder}"
        raise InputError(field, path, "a file in an existing folder", why)
    if p.is_dir():
        raise InputError(field, path, "a file name", "a folder")
    if not os.access(p if p.exists() else folder, os.W_OK):
        raise InputError(field, path, "a file this user may write", f"{p if p.exists() else folder} is not writable")
