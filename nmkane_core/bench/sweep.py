"""``nmkane bench`` rows of the sweep issue: scaling over cores and streaming memory.

* a 64-run sweep (sliding particle, Δt = 0.001, 500 s each; 20 s with ``--quick``) on one
  core (this process), on the local process executor and on a Dask ``LocalCluster`` of
  ``workers`` processes: the speedup over the one-core rate (targets ≥ 1.8× and ≥ 1.7× on 2
  cores).  Executors are started and warmed before the clock starts (their start-up time is
  in the note), and their rows are checked equal to the one-core rows;
* Dask's overhead per run: 640 runs of a few steps, Dask wall per run minus the one-core
  wall per run divided by the workers (target ≤ 5 ms);
* with ``--long`` only: the peak RSS of ``nmkane sweep`` processes writing 1,000 and 10,000
  runs to a CSV (flat: at most 20 MB more for ten times the runs).

Timings are wall times on a machine others may be using: the load average is in the notes.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

from ..sweep.executors import DaskExecutor, ProcessExecutor, SerialExecutor
from ..sweep.runner import run_sweep
from ..sweep.spec import sweep_spec

__all__ = ["sweep_rows"]

GRID = ["gamma1=-40:-5:8", "gamma2=-400:-25:8"]  # 64 runs
TINY_GRID = ["gamma1=-40:-1:32", "gamma2=-400:-10:20"]  # 640 runs
WARM_GRID = ["gamma1=-1,-2,-3,-4"]
RSS_FLAT_MB = 20.0


class _Memory:
    """A sweep sink that keeps the rows (the bench compares executors' rows)."""

    def __init__(self):
        self.done: set = set()
        self.rows: list[dict] = []

    def write(self, rows):
        self.rows.extend(rows)


def _timed(ex, base: dict, grid: list[str]) -> tuple[float, list[dict]]:
    sink = _Memory()
    t0 = time.perf_counter()
    run_sweep(base, sweep_spec(grid=grid), sink, executor=ex, progress=False)
    return time.perf_counter() - t0, sink.rows


def _same(a: list[dict], b: list[dict]) -> bool:
    """Equal rows (by point, whatever the completion order), wall times aside."""

    def key(rows):
        return sorted(
            ({k: v for k, v in r.items() if k != "wall_time_s"} for r in rows), key=lambda r: (r["gamma1"], r["gamma2"])
        )

    return key(a) == key(b)


def _load() -> str:
    if not hasattr(os, "getloadavg"):
        return ""
    one, five, _ = os.getloadavg()
    return f"load average {one:.1f} (5 min {five:.1f}) on {os.cpu_count()} CPUs"


def sweep_rows(add, quick: bool = False, long: bool = False, workers: int = 2) -> None:
    """Measure the sweep rows; ``add(workload, wall, evals, target, ok, note)`` records one
    (:func:`nmkane_core.bench.rows.run_bench`'s)."""
    horizon = 20.0 if quick else 500.0  # long enough that a run, not the scheduling, is what is timed
    base = {"system": "sliding-particle", "dt": 0.001, "t_final": horizon, "every": 10**6}
    tiny = {**base, "t_final": 0.01}
    one = _one_core_row(add, base, tiny, horizon)
    _process_row(add, base, tiny, one, workers)
    _dask_rows(add, base, tiny, one, workers)
    if long:
        _streaming_memory_row(add, workers)


class _OneCore:
    """The one-core reference: its rate (runs/s), rows and the tiny runs' time."""

    def __init__(self, rate: float, rows, tiny_seconds: float):
        self.rate, self.rows, self.tiny_seconds = rate, rows, tiny_seconds


N_RUNS = 64  # the grid's runs (GRID)
N_TINY = 640  # runs of 10 steps (TINY_GRID), for the overhead per run


def _one_core_row(add, base: dict, tiny: dict, horizon: float) -> _OneCore:
    with SerialExecutor() as ex:
        _timed(ex, tiny, WARM_GRID)
        t1, rows1 = _timed(ex, base, GRID)
        t1_tiny, _ = _timed(ex, tiny, TINY_GRID)
    rate1 = N_RUNS / t1
    add(
        f"sweep: {N_RUNS} sliding-particle runs, {horizon:g} s at dt=0.001, one core (this process)",
        t1,
        None,
        note=f"({rate1:.1f} runs/s; {_load()})",
    )
    return _OneCore(rate1, rows1, t1_tiny)


def _process_row(add, base: dict, tiny: dict, one: _OneCore, workers: int) -> None:
    t0 = time.perf_counter()
    with ProcessExecutor(workers) as ex:
        _timed(ex, tiny, WARM_GRID)  # the worker processes start and load the kernels
        start = time.perf_counter() - t0
        tp, rows_p = _timed(ex, base, GRID)
    speed = (N_RUNS / tp) / one.rate
    add(
        f"sweep: the same {N_RUNS} runs, local executor, {workers} processes",
        tp,
        None,
        "≥ 1.8× one core",
        speed >= 1.8 if (os.cpu_count() or 1) >= workers else None,
        f"({N_RUNS / tp:.1f} runs/s: {speed:.2f}× one core; start-up {start:.1f} s not counted; "
        f"rows {'equal' if _same(one.rows, rows_p) else 'DIFFERENT'}; {_load()})",
    )


def _dask_rows(add, base: dict, tiny: dict, one: _OneCore, workers: int) -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        add("sweep: Dask LocalCluster", 0.0, None, note="(skipped: pip install 'nmkane[sweep]')")
        return
    t0 = time.perf_counter()
    with DaskExecutor(f"local:{workers}", warm=(base,)) as ex:
        start = time.perf_counter() - t0
        _timed(ex, tiny, WARM_GRID)
        td, rows_d = _timed(ex, base, GRID)
        td_tiny, _ = _timed(ex, tiny, TINY_GRID)
    speed = (N_RUNS / td) / one.rate
    add(
        f"sweep: the same {N_RUNS} runs, Dask LocalCluster, {workers} worker processes",
        td,
        None,
        "≥ 1.7× one core",
        speed >= 1.7 if (os.cpu_count() or 1) >= workers else None,
        f"({N_RUNS / td:.1f} runs/s: {speed:.2f}× one core; cluster start-up {start:.1f} s not counted; "
        f"rows {'equal' if _same(one.rows, rows_d) else 'DIFFERENT'}; {_load()})",
    )
    over = td_tiny / N_TINY - one.tiny_seconds / (N_TINY * workers)
    add(
        f"sweep: Dask overhead per run ({N_TINY} runs of 10 steps)",
        max(over, 1e-9),
        None,
        "≤ 5 ms",
        over <= 0.005,
        f"(Dask {td_tiny / N_TINY * 1e3:.2f} ms/run wall vs one core {one.tiny_seconds / N_TINY * 1e3:.2f} ms/run "
        f"÷ {workers}; {_load()})",
    )


def _streaming_memory_row(add, workers: int) -> None:
    rss = {k: _sweep_peak_rss(k, workers) for k in (1_000, 10_000)}
    grow = rss[10_000][0] - rss[1_000][0]
    add(
        "sweep: 10,000 runs streamed to CSV (`nmkane sweep` process, peak RSS)",
        rss[10_000][1],
        None,
        f"≤ +{RSS_FLAT_MB:g} MB vs 1,000",
        grow <= RSS_FLAT_MB,
        f"(peak RSS {rss[10_000][0]:.0f} MB for 10,000 runs, {rss[1_000][0]:.0f} MB for 1,000; "
        f"{workers} worker processes; {_load()})",
    )


def _sweep_peak_rss(runs: int, workers: int) -> tuple[float, float]:
    """(peak RSS in MB, wall s) of an ``nmkane sweep`` process running ``runs`` tiny runs."""
    side = max(d for d in range(1, int(runs**0.5) + 1) if runs % d == 0)  # side × (runs / side) = runs
    args = ["sweep", "sliding-particle", "--t-final", "0.01", "--dt", "0.001"]
    args += ["--grid", f"gamma1=-50:-0.5:{side}", "--grid", f"gamma2=-500:-5:{runs // side}"]
    args += ["--workers", str(workers), "--no-progress"]
    with tempfile.TemporaryDirectory() as tmp, open(os.path.join(tmp, "err.txt"), "w+") as err:
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            [sys.executable, "-m", "nmkane_core.cli", *args, "--out", os.path.join(tmp, "s.csv")],
            stdout=subprocess.DEVNULL,
            stderr=err,
        )
        _, status, usage = os.wait4(proc.pid, 0)  # this child's own peak, not every child's
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            raise RuntimeError(f"nmkane sweep of {runs} runs failed: {err.read()[-500:]}")
    scale = 1.0 if sys.platform == "darwin" else 1024.0  # ru_maxrss: bytes on macOS, KiB on Linux
    return usage.ru_maxrss * scale / 2**20, wall
