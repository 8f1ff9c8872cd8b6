"""The tests' shared kernel cache, compiled once at the start of a run (see tests/conftest.py).

Every test process and every subprocess a test starts uses one kernel cache (``$NMKANE_CACHE_DIR``).
Under CI it starts empty (``.ci/run``), so before the first test it is warmed here, in parallel
processes, with what nearly every test module uses: for each of the systems in ORDER, every variant's
loops as ``nmkane serve`` warms them (fixed step and adaptive, with and without a projection),
the scipy adapter for the paper's two systems, and what the web app derives from a system (its
compiled visuals, its matrices panels); for every other built-in system, what the web app's own
warm-up loads of it (:func:`warm_page`).  Without it, two xdist workers compiled the same kernels
at once, each subprocess test paid for whatever the tests before it had not compiled yet, and each
browser test's app compiled the other systems in a background thread of the tests' process.

A stamp (a hash of the sources of ``nmkane_core``, ``backend``, ``web`` and this file, Python's and
the C compiler's) marks a warmed cache: a second run with nothing changed skips the warm-up.
Tests that need an empty cache on purpose (a first start, a first run) make their own.
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
# the systems nearly every test module runs: warmed whole (warm_system), the others as the web app warms them
ORDER = ("whipple-bicycle", "appell-hamel", "sliding-particle", "chaplygin-sleigh", "rolling-disk")
SCIPY_SYSTEMS = ("appell-hamel", "sliding-particle")  # the systems tests run with scipy's integrators
#: systems of ORDER no test runs with a projection: their projected loops are not warmed (the
#: bicycle's took 7 s of the warm-up's CPU; a fresh CI-like run, 2026-12-04, read every other
#: warmed loop and never these — a test that comes to need them compiles them on first use)
UNPROJECTED = ("whipple-bicycle",)
#: the order the two processes take the systems in: the longest first, so that they end together
#: (seconds each on an idle 2-core machine, empty cache, 2026-12-03: appell-hamel 57–74,
#: iftomm-a04 63–94, whipple-bicycle 41–54, sliding-particle 47–56, iftomm-a03 44–47, iftomm-a02
#: 36–44, the others under 31; taken in registry order, A04 started last and one process
#: worked alone for its last 20–30 s)
COSTLIEST_FIRST = (
    "appell-hamel",
    "iftomm-a04",
    "sliding-particle",
    "whipple-bicycle",
    "iftomm-a03",
    "iftomm-a02",
    "rolling-disk",
    "chaplygin-sleigh",
    "iftomm-a01",
    "iftomm-a05",
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
    """In a child process: load, or compile once, what the tests use of system ``name``."""
    t0 = time.perf_counter()
    from nmkane_core.run.registry import get_system

    system = get_system(name)
    loops = [
        {system.option: variant, "integrator": integrator, "projection": projection}
        for variant in system.variants
        for integrator in ("kutta-merson", "kutta-merson-adaptive")
        for projection in (("none",) if name in UNPROJECTED else ("none", "yoon"))
    ]
    _runs(system, loops + ([{"integrator": "rk45"}] if name in SCIPY_SYSTEMS else []))
    _page_parts(system)
    return name, time.perf_counter() - t0


def warm_page(name: str) -> tuple[str, float]:
    """In a child process: what the web app's own warm-up loads of system ``name`` (each
    variant's default run, its visuals, its matrices panels) — a system that few test modules
    run but every browser test's app warms in a background thread, which, compiling in the
    tests' process, held up the pages of the browser tests running beside it."""
    t0 = time.perf_counter()
    from nmkane_core.run.registry import get_system

    system = get_system(name)
    _runs(system, [{system.option: variant} for variant in system.variants])
    _page_parts(system)
    return name, time.perf_counter() - t0


def _child_init() -> None:
    # one compiling process per core: the loop's background precompile child would be a third
    os.environ["NMKANE_PRECOMPILE"] = "0"
    os.environ.setdefault("MPLBACKEND", "Agg")
    sys.path.insert(0, str(ROOT))


def _builtin_names() -> list[str]:
    from nmkane_core.run.registry import system_names

    # the systems nearly every test module runs; the others (the IFToMM benchmarks, the
    # odometer, the knife edge) get what the web app warms of them (warm_page)
    return [n for n in ORDER if n in system_names()]


def _other_names() -> list[str]:
    from nmkane_core.run.registry import system_names

    return [n for n in system_names() if n not in ORDER]


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
        names, others = _builtin_names(), _other_names()
        failed, took = [], {}
        ctx = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(processes, mp_context=ctx, initializer=_child_init) as pool:
            rank = {n: i for i, n in enumerate(COSTLIEST_FIRST)}
            jobs = [(warm_system, n) for n in names] + [(warm_page, n) for n in others]
            jobs.sort(key=lambda job: rank.get(job[1], len(rank)))  # stable: the rest as registered
            futures = {pool.submit(fn, n): n for fn, n in jobs}
            for future in concurrent.futures.as_completed(futures):
                try:
                    name, seconds = future.result()
                    took[name] = seconds
                except Exception:  # the tests of that system fail and say why
                    failed.append(futures[future])
                    log(f"warming {futures[future]} failed:\n{traceback.format_exc()}")
        detail = ", ".join(f"{n} {took[n]:.0f} s" for n in names + others if n in took)
        log(f"kernel cache {root} warmed in {time.perf_counter() - t0:.0f} s by {processes} processes ({detail})")
        if not failed:
            mark.touch()  # (stamps of other sources stay: worktrees of other branches share a cache)
        return not failed
