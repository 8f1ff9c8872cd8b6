"""Compile a new kernel's integrator loop in a second process, beside the first run.

A first run after install spends most of its time in numba, and numba compiles under a global
lock: one thing at a time in one process.  When a run is resolved with a kernel this process
has just generated (:mod:`nmkane_core.kernel.loader` records which), :func:`start` runs
``python -m nmkane_core.kernel.precompile <folder> <key> <loop> <projected>``, which compiles
the loop that run will call, for the signature it will call it with, into numba's disk cache;
meanwhile the first process derives the other models it needs and checks the initial state,
and before its own first loop call it waits for the child and loads the result (:func:`wait`).
Only the loop a run uses is compiled ahead: the others compile on their first use.

While it waits, the first process compiles the functions the loop calls that compile apart
from its stage loop (:func:`~nmkane_core.kernel.interface.callee_signatures`: the constraint
forces' solve, the diagnostics, the projection step), and the child, busy with the stage loop
meanwhile, loads them from the cache when it gets there: the two cores share the loop's
compilation instead of one doing it while the other waits.

Set ``NMKANE_PRECOMPILE=0`` to turn it off.
"""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
import threading
from pathlib import Path

from .interface import LOOPS, callee_signatures, fixed_loop_signature, loop_signature

_CHILDREN: dict[str, tuple[subprocess.Popen, bool]] = {}  # key -> (child, its loop is the projected one)
_FRESH: dict[str, Path] = {}  # kernels this process wrote (never compiled yet): key -> folder
_LOCK = threading.Lock()


def _key(module) -> str:
    """A loaded kernel's cache key (its module is ``nmkane_kernel_<key>``)."""
    return module.__name__.removeprefix("nmkane_kernel_")


def written(folder: Path, key: str) -> None:
    """Record that this process has just written kernel ``key`` (its loops are not compiled)."""
    with _LOCK:
        _FRESH[key] = folder


def start(module, loop: str = "integrate_fixed", projected: bool = False) -> None:
    """Start compiling ``module``'s ``loop`` (with or without a projection) in a child process,
    when this process has just written the module (no-op otherwise, and when disabled)."""
    if os.environ.get("NMKANE_PRECOMPILE", "1") == "0" or (os.cpu_count() or 1) < 2:
        return
    key = _key(module)
    with _LOCK:
        folder = _FRESH.pop(key, None)
        if folder is None or key in _CHILDREN:
            return
        command = [sys.executable, "-m", "nmkane_core.kernel.precompile", str(folder), key, loop, str(int(projected))]
        with contextlib.suppress(OSError):  # no second process: compile in this one
            child = subprocess.Popen(
                command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
            )
            _CHILDREN[key] = (child, projected)


def compiling(module) -> bool:
    """A child is compiling ``module``'s loop right now."""
    key = _key(module)
    with _LOCK:
        found = _CHILDREN.get(key)
    return found is not None and found[0].poll() is None


def uncompiled(module) -> bool:
    """This process wrote ``module`` and its loop is not compiled yet (none started, or a
    child is compiling it): a call into it would compile first."""
    key = _key(module)
    with _LOCK:
        if key in _FRESH:
            return True
    return compiling(module)


def wait(module, timeout: float = 300.0) -> None:
    """Wait for the child compiling ``module``'s loop, if one is running (compiling meanwhile
    what the loop calls apart from its stage loop)."""
    key = _key(module)
    with _LOCK:
        _FRESH.pop(key, None)  # the caller compiles or loads the loop next
        found = _CHILDREN.pop(key, None)
    if found is None:
        return
    proc, projected = found
    if proc.poll() is None:
        for name, signature in callee_signatures(module, projected).items():
            with contextlib.suppress(Exception):  # only a head start: the child compiles what is missing
                getattr(module, name).compile(signature)
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        proc.kill()  # this process compiles instead


def main(argv=None) -> int:
    from .cache import import_kernel

    args = list(argv or sys.argv[1:])
    folder, key = args[:2]
    loop = args[2] if len(args) > 2 else "integrate_fixed"
    projected = len(args) > 3 and args[3] == "1"
    module = import_kernel(Path(folder), key)
    signature = loop_signature(LOOPS[loop], projected) if loop in LOOPS else fixed_loop_signature()
    getattr(module, loop).compile(signature)
    return 0


if __name__ == "__main__":
    sys.exit(main())
