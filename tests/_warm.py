"""The tests' shared kernel cache, prepared once at the start of a run (see tests/conftest.py).

Every test process and every subprocess a test starts uses one kernel cache (``$NMKANE_CACHE_DIR``).
Under CI it starts empty (``.ci/run``), so before the first test it is warmed here, in parallel
processes: for every built-in system, each variant's model derived and its C functions compiled
(a short run of each, which also builds the compiled core once), and what the web app derives from
a system (its compiled visuals, its matrices panels).  Without it, two xdist workers derived the
same models at once, and each subprocess test paid for whatever the tests before it had not
derived yet.

A stamp (a hash of the sources of ``nmkane_core``, ``backend``, ``web`` — the C core's included —
this file and Python's version) marks a warmed cache: a second run with nothing changed skips the
warm-up.  Tests that need an empty cache on purpose (a first start, a first run) make their own.
"""

from __future__ import annotations

import concurrent.futures
import hashlib
import multiprocessing
import os
import sys
import time
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the order the processes take the systems in: the longest first, so that they end together
#: (seconds each on a 2-core machine, empty cache: iftomm-a04 31, whipple-bicycle 22, iftomm-a03 18,
#: appell-hamel 16, iftomm-a02 10, sliding-particle 6, the others under 5)
COSTLIEST_FIRST = (
    "iftomm-a04",
    "whipple-bicycle",
    "iftomm-a03",
    "appell-hamel",
    "iftomm-a02",
    "sliding-particle",
)


def stamp() -> str:
    """What the warm cache was made from: the sources that generate and load kernels."""
    h = hashlib.sha256(f"{sys.version}\0".encode())
    for package in ("nmkane_core", "backend", "web"):
        for path in sorted([*(ROOT / package).rglob("*.py"), *(ROOT / package).rglob("*.[ch]")]):
            h.update(str(path.relative_to(ROOT)).encode() + b"\0" + path.read_bytes())
    h.update(Path(__file__).read_bytes())
    return h.hexdigest()[:24]


def _runs(system, settings: list[dict]) -> None:
    from nmkane_core.run.simulate import simulate

    for one in settings:
        simulate({"system": system.name, "t_final": 0.05, **one}, progress=False)


def _page_parts(system) -> None:
    """What the web app derives from a system: its compiled visuals and its matrices panels."""
    from nmkane_core.kernel.visuals import compile_visuals

    compile_visuals(system)
    try:
        from web import matrices
    except ImportError:  # the web extra is not installed: its tests skip
        return
    for variant in system.variants:
        matrices.panel(system.name, variant)


def warm_system(name: str) -> tuple[str, float]:
    """In a child process: derive and compile every variant of system ``name``, and what the web
    app derives from it."""
    t0 = time.perf_counter()
    from nmkane_core.run.registry import get_system

    system = get_system(name)
    _runs(system, [{system.option: variant} for variant in system.variants])
    _page_parts(system)
    return name, time.perf_counter() - t0


def _child_init() -> None:
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.path.insert(0, str(ROOT))


def warm(root: Path, processes: int, log) -> bool:
    """Warm the cache at ``root`` (the stamp says whether it is) with ``processes`` processes;
    ``log(line)`` hears what was done.  Returns True when the cache is warm."""
    folder = root / "tests-warm"
    folder.mkdir(parents=True, exist_ok=True)
    mark = folder / stamp()
    if mark.exists():
        return True
    import fcntl

    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # another test run warming the same cache: wait for it
        if mark.exists():
            return True
        t0 = time.perf_counter()
        from nmkane_core.run.registry import system_names

        names = list(system_names())
        failed, took = [], {}
        ctx = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(processes, mp_context=ctx, initializer=_child_init) as pool:
            rank = {n: i for i, n in enumerate(COSTLIEST_FIRST)}
            ordered = sorted(names, key=lambda n: rank.get(n, len(rank)))  # stable: the rest as registered
            futures = {pool.submit(warm_system, n): n for n in ordered}
            for future in concurrent.futures.as_completed(futures):
                try:
                    name, seconds = future.result()
                    took[name] = seconds
                except Exception:  # the tests of that system fail and say why
                    failed.append(futures[future])
                    log(f"warming {futures[future]} failed:\n{traceback.format_exc()}")
        detail = ", ".join(f"{n} {took[n]:.0f} s" for n in names if n in took)
        log(f"kernel cache {root} warmed in {time.perf_counter() - t0:.0f} s by {processes} processes ({detail})")
        if not failed:
            mark.touch()  # (stamps of other sources stay: worktrees of other branches share a cache)
        return not failed
