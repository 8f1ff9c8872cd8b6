"""``nmkane bench`` rows of first use on an empty kernel cache, each in processes of their own:
a large model of the user's (the IFToMM A02 chain at N = 40, registered from a systems file and
run for the benchmark's 20 s) and a first ``nmkane serve`` (the REST API answering with the web
app listening, then every built-in system's every variant prepared)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

__all__ = ["startup_rows"]

ROOT = Path(__file__).resolve().parents[2]


def startup_rows(add, quick: bool) -> None:
    """Add the first-use rows (not with ``quick``: each derives models from nothing, for half a
    minute; the serve rows need the service and web extras)."""
    if quick:
        return
    _chain_row(add)
    _chain_warm_row(add)
    try:
        import uvicorn  # noqa: F401
        import viser  # noqa: F401
    except ImportError:  # the library alone: no service to start
        return
    _serve_rows(add)


def _chain_row(add) -> None:
    example = ROOT / "examples" / "iftomm_a02_n40.py"
    if not example.is_file():  # an installed package without the repository's examples
        return
    args = ["run", "iftomm-a02-n40", "--systems", str(example), "--t-final", "20", "--no-progress"]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        out = subprocess.run(
            [sys.executable, "-m", "nmkane_core.cli", *args],
            capture_output=True,
            text=True,
            env={**os.environ, "NMKANE_CACHE_DIR": tmp},
        )
        wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    add(
        "IFToMM A02 N = 40 (examples/iftomm_a02_n40.py): register + 20 s run, empty cache",
        wall,
        None,
        "≤ 15 s",
        wall <= 15.0,
        "(whole `nmkane run --systems` process: derivation, C functions, the run)",
    )


def _chain_warm_row(add) -> None:
    """The benchmark's N = 40 case, 20 s at its default step, warm: CPU and the error achieved."""
    from ..run.registry import register, system_names
    from ..run.simulate import simulate
    from ..systems import iftomm_a02

    system = iftomm_a02.iftomm_a02(40)
    if system.name not in system_names():
        register(system)
    settings = {"system": system.name, "t_final": 20.0, "every": 5}  # the benchmark's 400 output steps
    simulate(settings, progress=False)  # warm (derives the model on a first use)
    best = float("inf")
    for _ in range(2):
        t0 = time.process_time()
        run = simulate(settings, progress=False)
        best = min(best, time.process_time() - t0)
    qn, un = iftomm_a02.names(40)
    acc = iftomm_a02.acceptance(run.t, np.column_stack([run.state[k] for k in (*qn, *un)]), 40, energy=run.energy)
    add(
        f"IFToMM A02 N = 40, 20 s at its default dt = {run.settings['dt']:g}, warm, CPU time",
        best,
        None,
        "≤ 1 s",
        best <= 1.0 and max(acc["B0_position"], acc["B0_velocity"]) < 1e-3,
        f"({run.summary['status']}; B0 within {acc['B0_position']:.1e} m, {acc['B0_velocity']:.1e} m/s of the "
        f"exact motion (allowed 1e-3); max |ΔE| {acc['energy_drift']:.1e} J)",
    )


class _Lines:
    """A child's output lines as they come, with the time each arrived."""

    def __init__(self, proc: subprocess.Popen, t0: float):
        self.seen: list[tuple[float, str]] = []
        self._changed = threading.Condition()
        self._t0 = t0
        threading.Thread(target=self._read, args=(proc,), daemon=True).start()

    def _read(self, proc: subprocess.Popen) -> None:
        assert proc.stdout is not None
        for line in proc.stdout:
            with self._changed:
                self.seen.append((time.perf_counter() - self._t0, line.rstrip()))
                self._changed.notify_all()
        with self._changed:
            self.seen.append((time.perf_counter() - self._t0, "<exit>"))
            self._changed.notify_all()

    def when(self, pattern: str, timeout: float = 600.0) -> float:
        """Seconds from the start to the first line matching ``pattern``."""
        rx = re.compile(pattern)
        end = time.monotonic() + timeout
        with self._changed:
            while True:
                for t, line in self.seen:
                    if rx.search(line):
                        return t
                    if line == "<exit>":
                        raise RuntimeError("nmkane serve exited:\n" + "\n".join(s for _, s in self.seen))
                if not self._changed.wait(max(0.0, end - time.monotonic())):
                    raise RuntimeError(f"nmkane serve: no {pattern!r} within {timeout:g} s")


def _serve_rows(add) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NMKANE_CACHE_DIR": tmp, "NMKANE_DATA_DIR": tmp, "PYTHONUNBUFFERED": "1"}
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            [sys.executable, "-m", "nmkane_core.cli", "serve", "--api-port", "0", "--viser-port", "0"],
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            env=env,
            start_new_session=True,
        )
        lines = _Lines(proc, t0)
        try:
            page = lines.when(r"nmkane 3D web app\s+http")
            every = lines.when(r"the other variants ready in")
        finally:
            os.killpg(proc.pid, signal.SIGTERM)
            proc.wait(60)
    add(
        "first `nmkane serve` (empty cache): the REST API answers and the 3D web app listens",
        page,
        None,
        "≤ 15 s",
        page <= 15.0,
        "(every built-in system's default model prepared first)",
    )
    add("first `nmkane serve`: every built-in system's every variant runnable", every, None, "≤ 60 s", every <= 60.0)
