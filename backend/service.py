"""The run service: admission, the worker pool, the service's limits, and the store.

``execute`` is the whole life of a run, in a worker thread: resolve the settings (every
check of the core library), hold them to the service's limits, simulate with the wall
time limit, encode the run result document once (orjson, straight from the numpy
arrays), store it in one transaction, and hand the same bytes back for the 201.
"""

from __future__ import annotations

import asyncio
import math
import secrets
import threading
import time
from concurrent.futures import ThreadPoolExecutor

import orjson

from nmkane_core.integrate.drivers import ROWS_PER_CHUNK
from nmkane_core.run.accuracy import check_refined_budget
from nmkane_core.run.plan import Plan, check_budget, resolve
from nmkane_core.run.registry import get_system, system_names
from nmkane_core.run.result import Run
from nmkane_core.run.simulate import simulate
from nmkane_core.schema import RunSettings

from .config import Settings
from .store import RunStore, StoreFull

__all__ = ["RunService", "OutputGuard", "SweepAdmission", "checked_summary", "encode_document", "new_run_id"]


def new_run_id() -> str:
    """128 random bits, URL-safe: unguessable."""
    return secrets.token_urlsafe(16)


def checked_summary(run: Run) -> dict:
    """The run summary as JSON-ready data: the core made it through ``RunSummary`` already
    (every number finite, :mod:`nmkane_core.run.finish`), so this is a plain copy."""
    return dict(run.summary)


def encode_document(run: Run, run_id: str, summary: dict | None = None) -> bytes:
    """The run result document (``RunResult``) as JSON bytes, arrays straight from numpy.

    Equal to ``run.document(run_id).model_dump_json(by_alias=True)`` parsed, without
    building a million Python floats; the summary (small) goes through ``RunSummary`` so
    the document keeps to the schema.
    """
    if summary is None:
        summary = checked_summary(run)
    doc = {
        "id": run_id,
        "system": run.system,
        "settings": run.settings,
        "t": run.t,
        "state": run.state,
        "energy": run.energy,
        "violation": run.violation,
        "constraint_forces": run.constraint_forces,
        "multipliers": run.multipliers,
        "point_forces": run.point_forces,
        "summary": summary,
    }
    return orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY)


class OutputGuard:
    """The ``cancel`` callable of a run: stops it when the service stops, and stops an adaptive
    run whose output could pass ``max_rows``, so memory stays bounded whatever the tolerances
    (without it a 10 s adaptive run at rtol = 1e-14 makes 7 million rows, 2 GB).

    The library calls ``cancel()`` between chunks of work, and what a chunk can add is known:
    the driver of each kind of method says it (``ROWS_PER_CHUNK``: the compiled adaptive loop's
    output buffer, the scipy adapter's steps between checks).  While a run is switched to an
    equivalent model near a singular configuration its chunks are short, so at least
    ``MIN_CALLS`` calls are always allowed (at most ~400,000 rows, ~50 MB, before the output
    is thinned to ``max_rows``).  A ``max_rows`` argument to ``simulate`` would make this
    exact (see the notes to the core).  Fixed-step runs are checked before they start.
    """

    MIN_CALLS = 100

    def __init__(self, plan: Plan, max_rows: int, stopping: threading.Event):
        self.stopping = stopping
        self.max_rows = max_rows
        self.calls = 0
        self.hit = False
        rows_of = ROWS_PER_CHUNK[plan.integrator.kind]  # None: a fixed-step run's rows are known ahead
        per_call = None if rows_of is None else rows_of(plan.every)
        self.max_calls = None if per_call is None else max(self.MIN_CALLS, (max_rows - 2) // per_call)

    def __call__(self) -> bool:
        if self.stopping.is_set():
            return True
        if self.max_calls is not None:
            self.calls += 1
            if self.calls > self.max_calls:
                self.hit = True
                return True
        return False

    def explain(self, run: Run) -> None:
        """Say in the summary why the run stopped early."""
        if self.hit and run.summary["status"] == "timeout":
            run.summary["message"] = (
                f"stopped at t = {run.summary['t_end']:.6g} s by this service's bound on the output of an "
                f"adaptive run (max_rows = {self.max_rows:,}); results up to there are kept — raise `every` "
                "or shorten t_final"
            )


class SweepAdmission:
    """Sweeps under the service's admission: at most ``max_sweeps`` admitted (running plus
    queued; they run one at a time, in order), what is left of each, their runs on the run
    workers now, and the measured seconds per sweep run (for Retry-After and /api/health).

    ``stored_bytes``: the bytes of every sweep's stored rows and request, counted with the
    runs' against ``max_store_bytes`` (kept by the sweep manager)."""

    MAX_RETRY_S = 3600

    def __init__(self, max_sweeps: int, workers: int):
        self.max_sweeps, self.workers = max_sweeps, workers
        self._lock = threading.Lock()
        self.remaining: dict[str, int] = {}  # admitted sweeps, in queue order: runs not done yet
        self.started: set[str] = set()
        self.runs_running = 0  # sweep runs on the run workers now
        self.mean_run_s = 0.05  # moving average of a sweep run's time in a worker
        self.stored_bytes = 0

    def admit(self, sweep_id: str, total: int) -> bool:
        with self._lock:
            if len(self.remaining) >= self.max_sweeps:
                return False
            self.remaining[sweep_id] = total
            return True

    def start(self, sweep_id: str) -> None:
        with self._lock:
            self.started.add(sweep_id)

    def progress(self, sweep_id: str, runs: int) -> None:
        with self._lock:
            if sweep_id in self.remaining:
                self.remaining[sweep_id] = max(0, self.remaining[sweep_id] - runs)

    def release(self, sweep_id: str) -> None:
        with self._lock:
            self.remaining.pop(sweep_id, None)
            self.started.discard(sweep_id)

    def stored(self, nbytes: int) -> None:
        with self._lock:
            self.stored_bytes += nbytes

    def run_started(self) -> None:
        with self._lock:
            self.runs_running += 1

    def run_ended(self, seconds: float) -> None:
        with self._lock:
            self.runs_running -= 1
            self.mean_run_s += 0.1 * (seconds - self.mean_run_s)

    def counts(self) -> tuple[int, int, int]:
        """(sweeps running, sweeps queued, their runs not done yet)."""
        with self._lock:
            running = len(self.started & self.remaining.keys())
            return running, len(self.remaining) - running, sum(self.remaining.values())

    def retry_after(self) -> int:
        """Seconds until a place frees: the first admitted sweep's (the running one's) remaining
        runs × the measured seconds per run ÷ the sweep's workers (at least 1, at most an hour)."""
        with self._lock:
            head = next(iter(self.remaining.values()), 0)
            wait = head * self.mean_run_s / self.workers
        return int(min(self.MAX_RETRY_S, max(1, math.ceil(wait))))


class RunService:
    """Worker pool, admission control and the run store of one app."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self._warm_interrupted = threading.Event()
        #: set once the background warm-up (if any) has finished
        self.warmed = threading.Event()
        self.warmed.set()
        self.admitted = 0  # running + waiting
        self.running = 0
        self.waiting = 0  # admitted runs waiting for a worker (a sweep starts no run meanwhile)
        self._worker_freed = threading.Condition(self._lock)
        self.sweeps = SweepAdmission(settings.max_sweeps, settings.sweep_share)
        self._mean_run_s = 0.05  # moving average of a run's time in a worker (for Retry-After)
        self.store: RunStore | None = None
        self.pool: ThreadPoolExecutor | None = None  # simulations (CPU)
        self.writer: ThreadPoolExecutor | None = None  # commits (disk), one at a time

    # -- life ---------------------------------------------------------------------------

    def opened_store(self) -> RunStore:
        """The run store of a started service (routes run only between start and stop)."""
        if self.store is None:
            raise RuntimeError("the run service is not started")
        return self.store

    def start(self) -> None:
        """Open the store and the pool (again, after a stop: an app can have several lifespans)."""
        with self._lock:
            # a new event for each lifespan: a warm-up thread of an earlier one, still finishing
            # its step, holds the event that stopped it and is not woken by this start
            if self._stopping.is_set():
                self._stopping = threading.Event()
            if self.store is None:
                self.store = RunStore(self.settings.database, self.settings.store_cap)
            if self.pool is None:
                self.pool = ThreadPoolExecutor(
                    max_workers=self.settings.max_concurrent_runs, thread_name_prefix="nmkane-run"
                )
            if self.writer is None:
                self.writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="nmkane-store")

    def stop(self) -> None:
        """Stop: running simulations end now (as ``timeout``), queued ones are dropped; every
        run handed to the writer is committed before the store closes."""
        self._stopping.set()
        with self._lock:
            pool, writer, store = self.pool, self.writer, self.store
            self.pool = self.writer = self.store = None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)
        if writer is not None:
            writer.shutdown(wait=True)
        if store is not None:
            store.close()

    @property
    def warm_interrupted(self) -> bool:
        """Whether :meth:`interrupt_warm` was called."""
        return self._warm_interrupted.is_set()

    def interrupt_warm(self) -> None:
        """Stop the warm-up after the step under way (a stop asked while the service starts:
        ``serve`` then stops the service as it would after a start)."""
        self._warm_interrupted.set()

    def warm_steps(self) -> tuple[list, list]:
        """The warm-up runs: ``(first, later)``, each a list of ``(label, settings)``.

        ``first``: what a request that names only a system runs — each system's default
        variant — loaded before the service answers.  ``later``: the other variants, loaded in
        the background while the service answers.  Every integrator and projection runs in the
        one compiled core: a model needs only its derivation and its own C functions."""
        first: list[tuple[str, dict]] = []
        later: list[tuple[str, dict]] = []
        for name in system_names():
            system = get_system(name)
            for variant in system.variants:
                base = {"system": name, system.option: variant, "t_final": 0.05}
                (first if variant == system.default_variant else later).append((f"{name} {variant}", base))
        return first, later

    def warm(self, report=None, steps=None, title: str = "kernels") -> None:
        """Load (or compile once) the kernels and loops of ``steps`` (default: every one of
        :meth:`warm_steps`), so no request pays for it.

        ``report(line)`` (optional) hears one line per step; a first start after install
        derives each model and compiles its C functions (about 13 s for the 12 built-in systems
        on two cores), later starts load them from the cache.  Stops early when the service
        stops (or :meth:`interrupt_warm`), after the step under way, and says so.
        """
        start = time.perf_counter()
        stopping = self._stopping  # this lifespan's (start() makes a new one after a stop)
        if steps is None:
            first, later = self.warm_steps()
            steps = first + later
        for i, (label, settings) in enumerate(steps, 1):
            if stopping.is_set() or self._warm_interrupted.is_set():
                if report is not None:
                    report(
                        f"nmkane: {title} stopped with the service after {i - 1} of {len(steps)} "
                        "(the step under way was finished first; the next start prepares the rest)"
                    )
                return
            t0 = time.perf_counter()
            simulate(settings, progress=False)
            if report is not None:
                report(f"nmkane: {title} [{i}/{len(steps)}] {label}: {time.perf_counter() - t0:.1f} s")
        if report is not None:
            report(
                f"nmkane: {title} ready in {time.perf_counter() - start:.1f} s (kept in the kernel cache: "
                "later starts load them)"
            )

    def warm_in_background(self, steps, report=None, title: str = "the other variants") -> threading.Thread:
        """Warm ``steps`` in a daemon thread (requests are served meanwhile; one that needs a
        model still being prepared waits for it). :attr:`warmed` is set when it has finished."""
        self.warmed.clear()

        def work():
            try:
                self.warm(report, steps, title)
            finally:
                self.warmed.set()

        thread = threading.Thread(target=work, daemon=True, name="nmkane-warm")
        thread.start()
        return thread

    # -- admission ----------------------------------------------------------------------
    def admit(self) -> bool:
        with self._lock:
            if self.pool is None or self.admitted >= self.settings.queue_limit:
                return False
            self.admitted += 1
            return True

    async def run(self, settings: RunSettings) -> tuple[str, bytes]:
        """Simulate in a run worker, then commit in the writer thread (so run workers never
        wait for the disk); returns once the run is on disk. The caller holds an admission."""
        loop = asyncio.get_running_loop()
        pool, writer, store = self.pool, self.writer, self.store
        if pool is None or writer is None or store is None:
            raise RuntimeError("the run service is not running")
        ticket = [True]  # waiting for a worker
        with self._lock:
            self.waiting += 1
        try:
            run_id, body, record = await loop.run_in_executor(pool, self._execute_waited, settings, ticket)
        finally:
            self._unwait(ticket)  # also when the run never started (cancelled)
        self.check_store_room(store, len(record[3]) + len(record[4]) + len(record[5]))
        await loop.run_in_executor(writer, store.insert, record, self.sweeps.stored_bytes)
        return run_id, body

    def _execute_waited(self, settings: RunSettings, ticket: list[bool]) -> tuple[str, bytes, tuple]:
        self._unwait(ticket)
        return self.execute(settings)

    def _unwait(self, ticket: list[bool]) -> None:
        with self._lock:
            if ticket[0]:
                ticket[0] = False
                self.waiting -= 1
                self._worker_freed.notify_all()

    def sweep_may_start_run(self, timeout: float = 0.0) -> bool:
        """Whether a sweep may hand the run workers another run now: no interactive run waits
        for a worker (runs first); waits up to ``timeout`` s for that."""
        with self._lock:
            if self.waiting and timeout > 0 and not self._stopping.is_set():
                self._worker_freed.wait(timeout)
            return self.waiting == 0

    def check_store_room(self, store: RunStore, need: int) -> None:
        """:class:`StoreFull` when a run of ``need`` bytes would pass ``max_store_bytes`` with the
        sweeps' rows counted too (policy ``refuse``; the store checks its runs again)."""
        cap = store.cap
        if cap.policy == "refuse" and store.size + self.sweeps.stored_bytes + need > cap.max_bytes:
            raise StoreFull(cap, store.count(), store.size + self.sweeps.stored_bytes, need)

    def release(self) -> None:
        with self._lock:
            self.admitted -= 1

    def retry_after(self) -> int:
        """Seconds until the queue has drained, roughly (at least 1)."""
        with self._lock:
            backlog = max(self.admitted, 1) * self._mean_run_s / self.settings.max_concurrent_runs
        return int(min(60, max(1, math.ceil(backlog))))

    # -- a run --------------------------------------------------------------------------
    def check_limits(self, plan: Plan) -> None:
        """The service's own limits (the library's are checked by ``resolve``, the same way);
        adaptive runs are bounded while running: OutputGuard and max_wall_time_s."""
        s = self.settings
        check_budget(plan.integrator, plan.dt, plan.t_final, plan.every, s.max_steps, s.max_rows, " on this service")
        check_refined_budget(plan, s.max_steps, " on this service")  # error_estimate's second run, at dt/2

    def execute(self, settings: RunSettings) -> tuple[str, bytes, tuple]:
        """Resolve, check, simulate, encode (in a run worker); returns the id, the document
        bytes and the record for :meth:`RunStore.insert` (in the writer thread)."""
        with self._lock:
            self.running += 1
        t0 = time.perf_counter()
        try:
            plan = resolve(settings, max_rows=self.settings.max_rows)
            self.check_limits(plan)
            guard = OutputGuard(plan, self.settings.max_rows, self._stopping)
            # the wall limit bounds the whole request in its worker: what resolving took (a model's
            # first use derives it) is taken from the integration's share
            left = max(0.0, self.settings.max_wall_time_s - (time.perf_counter() - t0))
            run = simulate(plan, progress=False, time_limit=left, cancel=guard)
            guard.explain(run)
            run.thin(self.settings.max_rows, f"service limit max_rows = {self.settings.max_rows:,}")
            run_id = new_run_id()
            summary = checked_summary(run)
            body = encode_document(run, run_id, summary)
            store = self.store
            if store is None:
                raise RuntimeError("the service is stopping")
            return run_id, body, store.record(run_id, run.system, run.status, run.settings, summary, body)
        finally:
            with self._lock:
                self.running -= 1
                self._mean_run_s += 0.1 * (time.perf_counter() - t0 - self._mean_run_s)
