"""Compile a new kernel's integrator loop in a second process, beside the first run.

A first run after install spends most of its time in numba: the initial-state helpers
(``state_terms``, ``diagnostics_rows``) and the fixed-step loop (``integrate_fixed`` with the
right-hand side inside it), one after the other in one process because numba compiles
under a global lock.  When :mod:`nmkane_core.kernel.codegen` writes a new kernel module it starts
``python -m nmkane_core.kernel.precompile <folder> <key>``, which compiles the loop for the
signature every unprojected fixed-step run uses, into numba's disk cache; meanwhile the
first process compiles the helpers, and before its own first loop call it waits for the
child and loads the result (:func:`wait`).  On a machine with two cores this takes about a
fifth off the first run; with one core it costs nothing but a process start.

Set ``NMKANE_PRECOMPILE=0`` to turn it off.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
from pathlib import Path

from .interface import fixed_loop_signature  # the one definition of the loop's arguments (FixedArgs)

_CHILDREN: dict[str, subprocess.Popen] = {}
_LOCK = threading.Lock()


def start(folder: Path, key: str) -> None:
    """Start compiling the loop of kernel ``key`` in a child process (no-op when disabled)."""
    if os.environ.get("NMKANE_PRECOMPILE", "1") == "0" or (os.cpu_count() or 1) < 2:
        return
    with _LOCK:
        if key in _CHILDREN:
            return
        with contextlib.suppress(OSError):  # no second process: compile in this one
            _CHILDREN[key] = subprocess.Popen(
                [sys.executable, "-m", "nmkane_core.kernel.precompile", str(folder), key],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )


def wait(module, timeout: float = 300.0) -> None:
    """Wait for the child compiling ``module``'s loop, if one is running."""
    key = module.__name__.removeprefix("nmkane_kernel_")
    with _LOCK:
        proc = _CHILDREN.pop(key, None)
    if proc is None:
        return
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()  # this process compiles instead


def main(argv=None) -> int:
    from .cache import import_kernel

    folder, key = (argv or sys.argv[1:])[:2]
    module = import_kernel(Path(folder), key)
    module.integrate_fixed.compile(fixed_loop_signature())
    return 0


if __name__ == "__main__":
    sys.exit(main())
