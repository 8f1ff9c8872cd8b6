"""Where a sweep's runs happen: this process, local worker processes, or a Dask cluster.

Every executor runs *batches*: a task is ``run_batch(systems, base, points)``, which runs a
few points with the same base settings and returns one row (a dict) per point.  Batches keep
the per-run scheduling overhead small; at most a few batches per worker are in flight, so a
sweep of 10⁵ runs never holds more than those in memory (rows stream to the output as
batches finish, in completion order).

Workers load plug-in systems (``--systems``: file paths or modules, which must exist on
every worker) and the kernels once per process, in `init_worker`: the process pool
calls it as its initializer, a Dask cluster through ``Client.run`` before the first task;
``run_batch`` calls it too (a no-op once done), so a worker that joins later is ready on its
first task.

Dask (``pip install 'nmkane[sweep]'``): ``dask_executor("local")`` or ``"local:N"`` starts a
``distributed.LocalCluster`` of N single-threaded worker processes; ``"tcp://HOST:PORT"``
connects to a running scheduler, whose workers must have nmkane installed (the same version)
and the plug-in system files at the same paths.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import math
import multiprocessing
import os
from collections.abc import Iterable, Iterator

from ..errors import InputError, NmkaneError
from .spec import apply_point

__all__ = [
    "DaskExecutor",
    "ProcessExecutor",
    "SerialExecutor",
    "batch_size",
    "init_worker",
    "make_executor",
    "run_batch",
    "run_point",
]

_READY: set = set()


def init_worker(systems: tuple[str, ...] = (), warm: tuple[dict, ...] = ()) -> None:
    """Load plug-in systems and prepare the kernels of ``warm`` settings, once per process."""
    key = (tuple(systems), repr(warm))
    if key in _READY:
        return
    from ..run.plan import resolve
    from ..run.plugins import load_systems
    from ..run.simulate import prepare

    load_systems(list(systems), strict=True)
    for settings in warm:
        with contextlib.suppress(InputError):  # a combination the sweep reports as invalid
            prepare(resolve(settings))
    _READY.add(key)


def run_point(base: dict, point: dict, time_limit: float | None = None) -> dict:
    """One run as a sweep row: the point's values, then status and the summary's numbers.

    A point whose settings are refused gives status ``invalid`` and the reason in ``message``
    (a sweep does not stop for one bad combination)."""
    from ..run.simulate import simulate

    row = dict(point)
    try:
        run = simulate(apply_point(base, point), progress=False, time_limit=time_limit)
    except InputError as e:
        row.update(status="invalid", message=str(e))
        return row
    except NmkaneError as e:
        row.update(status="failed", message=str(e))
        return row
    s = run.summary
    row.update(status=s["status"], message=s["message"])
    for name, v in s["max_abs_violation"].items():
        row[f"max_abs_violation.{name}"] = v
    row.update(
        max_abs_energy_drift=s["max_abs_energy_drift"],
        final_energy_drift=s["final_energy_drift"],
        steps=s["steps"],
        wall_time_s=s["wall_time_s"],
    )
    return row


def run_batch(
    systems: tuple[str, ...],
    base: dict,
    points: list[dict],
    warm: tuple[dict, ...] = (),
    time_limit: float | None = None,
) -> list[dict]:
    """Run ``points`` (each {name: value}) over ``base`` settings; one row each (a worker's task)."""
    init_worker(systems, warm)
    return [run_point(base, p, time_limit) for p in points]


def batch_size(n_runs: int, workers: int, most: int = 64) -> int:
    """Runs per task: about 8 tasks per worker (load balance), at most ``most``."""
    return max(1, min(most, math.ceil(n_runs / (8 * max(1, workers)))))


def _batches(points: Iterable[dict], size: int) -> Iterator[list[dict]]:
    batch: list[dict] = []
    for p in points:
        batch.append(p)
        if len(batch) == size:
            yield batch
            batch = []
    if batch:
        yield batch


class _Executor:
    """Runs batches and yields their rows as they finish (at most ``2 × workers`` batches in flight)."""

    workers = 1
    name = "serial"

    def __init__(self, systems=(), warm=(), time_limit=None):
        self.systems, self.warm, self.time_limit = tuple(systems), tuple(warm), time_limit

    def rows(self, base: dict, points: Iterable[dict], size: int) -> Iterator[list[dict]]:
        raise NotImplementedError

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class SerialExecutor(_Executor):
    """In this process, one run after another (the one-core reference)."""

    def rows(self, base, points, size):
        for batch in _batches(points, size):
            yield run_batch(self.systems, base, batch, self.warm, self.time_limit)


class ProcessExecutor(_Executor):
    """A ``ProcessPoolExecutor`` of ``workers`` processes (spawned; each loads the kernels once)."""

    name = "processes"

    def __init__(self, workers: int | None = None, **kw):
        super().__init__(**kw)
        self.workers = workers or os.cpu_count() or 1
        self.pool = cf.ProcessPoolExecutor(
            self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=init_worker,
            initargs=(self.systems, self.warm),
        )

    def rows(self, base, points, size):
        pending: set = set()
        it = _batches(points, size)

        def fill():
            for batch in it:
                pending.add(self.pool.submit(run_batch, self.systems, base, batch, self.warm, self.time_limit))
                if len(pending) >= 2 * self.workers:
                    break

        fill()
        while pending:
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for f in done:
                pending.discard(f)
                yield f.result()
            fill()

    def close(self):
        self.pool.shutdown(wait=True, cancel_futures=True)


class DaskExecutor(_Executor):
    """A ``distributed.Client``: of a LocalCluster it starts, or of a scheduler at an address."""

    name = "dask"

    def __init__(self, where: str, **kw):
        super().__init__(**kw)
        try:
            import logging

            from distributed import Client, LocalCluster
        except ImportError:
            raise NmkaneError("--dask needs dask.distributed: pip install 'nmkane[sweep]'") from None
        self.cluster = None
        if where == "local" or where.startswith("local:"):
            n = os.cpu_count() or 1
            if where.startswith("local:"):
                try:
                    n = int(where[6:])
                except ValueError:
                    n = 0
                if n < 1:
                    raise InputError("--dask", where, "local, local:N (N ≥ 1 worker processes) or tcp://HOST:PORT")
            import dask

            # the statistical profiler samples the task thread every 10 ms: CPU a busy machine lacks
            with dask.config.set({"distributed.worker.profile.enabled": False}):
                self.cluster = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                    silence_logs=logging.ERROR,
                )
            self.client = Client(self.cluster)
        elif "://" in where:
            try:
                self.client = Client(where, timeout="10s")
            except (OSError, TimeoutError) as e:
                raise InputError(
                    "--dask", where, "the address of a running Dask scheduler", f"cannot connect: {e}"
                ) from None
        else:
            raise InputError("--dask", where, "local, local:N or tcp://HOST:PORT", "unknown form")
        self.workers = max(1, sum(self._threads().values()))
        self.client.run(init_worker, self.systems, self.warm)  # every worker loads the kernels now

    def _threads(self) -> dict:
        return self.client.nthreads()

    def rows(self, base, points, size):
        from distributed import as_completed

        it = _batches(points, size)
        # base and options travel once per worker, not once per task; as a list of one under a
        # fresh key (a dict would be scattered value by value under its own keys, "dt", ..., which
        # the next sweep on this client reuses while the cluster releases the old ones)
        base_f = self.client.scatter([base], broadcast=True, hash=False)[0]

        def submit(b):
            return self.client.submit(
                run_batch,
                self.systems,
                base_f,
                b,
                self.warm,
                self.time_limit,
                pure=False,
            )

        first = [submit(b) for _, b in zip(range(2 * self.workers), it, strict=False)]
        ac = as_completed(first)
        for f in ac:
            yield f.result()
            f.release()
            nxt = next(it, None)
            if nxt is not None:
                ac.add(submit(nxt))

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def make_executor(dask: str | None = None, workers: int | None = None, **kw) -> _Executor:
    """The executor for ``--dask`` / ``--workers``: Dask if named, else processes (1 worker: this process)."""
    if dask:
        return DaskExecutor(dask, **kw)
    workers = workers or os.cpu_count() or 1
    if workers == 1:
        return SerialExecutor(**kw)
    return ProcessExecutor(workers, **kw)
