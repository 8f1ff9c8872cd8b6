"""Sweeps over REST: many runs in the background, progress and rows fetched by id.

    POST /api/sweeps              body = {settings, grid, log_grid, sample, samples, seed}
                                  (the texts of ``nmkane sweep``'s options) -> 202 + id
    GET  /api/sweeps/{id}         status, progress and the rows so far (?offset=&limit=)
    GET  /api/sweeps/{id}.csv     the rows as CSV (the columns of ``nmkane sweep --out``)

A sweep is checked before the 202 (every varied value against the system; its size against
the setting ``max_sweep_runs``, ``NMKANE_MAX_SWEEP_RUNS``, default 10,000; its longest run
against the service's ``max_steps``): bad input answers 422 naming the field.

Sweeps are under the service's admission (:class:`backend.service.SweepAdmission`): at most
``max_sweeps`` (``NMKANE_MAX_SWEEPS``, default 2) are admitted, running plus queued; a further
POST answers 503 with a Retry-After of the running sweep's remaining runs × the measured
seconds per run ÷ its workers.  Sweeps run one at a time, their runs on the service's run
workers — at most ``sweep_workers`` (``NMKANE_SWEEP_WORKERS``; unset, half of them) at once,
one run per task, and none started while an interactive run waits for a worker (runs first)
— or on the Dask scheduler of the setting ``dask_scheduler``, ``NMKANE_DASK_SCHEDULER``
(``tcp://HOST:PORT``; its workers need nmkane installed).  ``/api/health`` counts them.

Rows are stored in the service's SQLite file (tables ``sweeps`` and ``sweep_rows``), batch by
batch, each batch in one transaction, and count with the runs against ``max_store_bytes``: a
sweep whose rows would pass it stops ``failed``, saying so (its rows so far kept), and a new
one is refused with 507.  A sweep whose rows cannot be written (a full disk) ends ``failed``
with the store's message; when even that cannot be written, the state is kept in memory and
served until the store takes it.

A sweep left ``queued`` or ``running`` by a process that is gone (killed, the machine
restarted) is marked ``interrupted`` when the service starts; see :mod:`backend.sweep_store`.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import io
import logging
import math
import secrets
import threading
import time
from typing import Annotated

import orjson
from fastapi import APIRouter, Depends, FastAPI, Path, Query, Request
from fastapi.responses import JSONResponse, Response
from pydantic import BaseModel, ConfigDict, Field

from nmkane_core.errors import InputError
from nmkane_core.run.registry import system_names
from nmkane_core.sweep.executors import _Executor, run_batch
from nmkane_core.sweep.output import columns as output_columns
from nmkane_core.sweep.runner import constraint_columns, run_sweep
from nmkane_core.sweep.spec import MAX_POINTS, SEED_MAX, SweepSpec, sweep_spec

from .config import Settings
from .deps import AppSettings
from .errors import error_doc, error_response, item, not_found
from .models import RunSettings
from .service import RunService
from .store import StoreError, StoreFull
from .sweep_store import SweepStore, owner_alive, process_owner

__all__ = ["SweepManager", "SweepRequest", "SweepStore", "owner_alive", "process_owner", "router"]


@contextlib.asynccontextmanager
async def _lifespan(app):
    """At the service's start: open the sweep store, so sweeps a stopped service left running
    are marked ``interrupted`` before the first request."""
    if getattr(app, "state", None) is not None and hasattr(app.state, "settings"):
        _manager_of(app)
    yield


log = logging.getLogger("nmkane.backend")
router = APIRouter(lifespan=_lifespan)
SWEEP_ID = Path(description="the sweep's id, as returned by POST /api/sweeps", min_length=1, max_length=64)


class SweepRequest(BaseModel):
    """A sweep: base run settings and what varies (the texts of ``nmkane sweep``'s options)."""

    model_config = ConfigDict(
        extra="forbid",
        json_schema_extra={
            "examples": [
                {
                    "settings": {"system": "sliding-particle", "t_final": 2},
                    "grid": ["gamma1=-40:-10:4"],
                    "log_grid": ["gamma2=-10:-1000:3"],
                }
            ]
        },
    )

    settings: RunSettings = Field(default_factory=lambda: RunSettings(), description="the base run settings")
    grid: list[str] = Field(
        default_factory=list, max_length=8, description="NAME=START:STOP:NUM (both ends included) or NAME=V1,V2,..."
    )
    log_grid: list[str] = Field(default_factory=list, max_length=8, description="NAME=START:STOP:NUM, log-spaced")
    sample: list[str] = Field(default_factory=list, max_length=8, description="NAME=LOW:HIGH (Latin hypercube)")
    samples: int | None = Field(
        None, ge=1, le=MAX_POINTS, description="Latin-hypercube points (and at most the service's max_sweep_runs)"
    )
    seed: int = Field(0, ge=0, le=SEED_MAX, description="Latin-hypercube seed, an integer in [0, 2³² − 1]")


class SweepCreated(BaseModel):
    id: str
    status: str
    total: int


class SweepState(BaseModel):
    id: str
    created: float
    system: str
    status: str = Field(description="queued | running | done | failed | interrupted (the service stopped)")
    total: int
    done: int
    columns: list[str]
    rows: list[dict]
    offset: int
    message: str = ""


class _Sink:
    """run_sweep's output: rows into the store, within ``max_store_bytes`` (``done`` is empty:
    a REST sweep starts fresh)."""

    def __init__(self, manager: SweepManager, sweep_id: str):
        self.manager, self.store, self.id, self.n = manager, manager.store, sweep_id, 0
        self.done: set = set()

    def write(self, rows):
        clean = [
            {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()} for r in rows
        ]
        sizes = [len(orjson.dumps(r)) for r in clean]
        fit = self.manager.rows_that_fit(sizes)
        if fit:
            self.store.add_rows(self.id, self.n, clean[:fit])
            self.n += fit
            self.manager.admission.stored(sum(sizes[:fit]))
            self.manager.admission.progress(self.id, fit)
        if fit < len(rows):
            self.manager.check_room(sum(sizes[fit:]))  # raises StoreFull, saying how full


class PoolExecutor(_Executor):
    """A sweep's runs on the service's run workers (the compiled loops release the GIL), under its
    admission: one run per task, at most ``workers`` (the sweep's share) in flight, none started
    while an interactive run waits for a worker.  Rows are handed on ``size`` at a time (one
    transaction each), or each second."""

    name = "service-pool"

    def __init__(self, service: RunService, workers: int, **kw):
        super().__init__(**kw)
        self.service, self.workers = service, workers

    def _run(self, base: dict, point: dict) -> list[dict]:
        admission = self.service.sweeps
        admission.run_started()
        t0 = time.perf_counter()
        try:
            return run_batch(self.systems, base, [point], (), self.time_limit)
        finally:
            admission.run_ended(time.perf_counter() - t0)

    def _submit(self, base: dict, point: dict) -> cf.Future:
        pool = self.service.pool
        if pool is None:
            raise RuntimeError("the run service is stopping")
        return pool.submit(self._run, base, point)

    def rows(self, base, points, size):
        pending: set = set()
        it, more, ready, last = iter(points), True, [], time.perf_counter()
        while more or pending:
            while more and len(pending) < self.workers and self.service.sweep_may_start_run(0 if pending else 0.1):
                point = next(it, None)
                if point is None:
                    more = False
                else:
                    pending.add(self._submit(base, point))
            if not pending:  # interactive runs have the workers: wait for them (or the service's stop)
                if self.service.pool is None:
                    raise RuntimeError("the run service is stopping")
                continue
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for f in done:
                pending.discard(f)
                ready.extend(f.result())
            if ready and (len(ready) >= size or time.perf_counter() - last >= 1.0 or not (more or pending)):
                yield ready
                ready, last = [], time.perf_counter()


class SweepManager:
    """The store, the admission (the run service's :class:`~backend.service.SweepAdmission`)
    and the one thread that runs sweeps in order."""

    def __init__(self, settings: Settings, service: RunService):
        self.settings, self.service = settings, service
        self.store = SweepStore(settings.database)
        self.admission = service.sweeps
        self.admission.stored_bytes = self.store.size()
        self.queue = cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="nmkane-sweep")
        self._lock = threading.Lock()
        #: final states the store could not take (a full disk): served by GET, written when it can
        self.unwritten: dict[str, tuple[str, str]] = {}

    def executor(self):
        limit = self.settings.max_wall_time_s
        if self.settings.dask_scheduler is not None:
            from nmkane_core.sweep.executors import DaskExecutor

            return DaskExecutor(self.settings.dask_scheduler, time_limit=limit)
        if self.service.pool is None:
            self.service.start()
        if self.service.pool is None:  # stopped meanwhile
            raise RuntimeError("the run service is stopping")
        return PoolExecutor(self.service, self.settings.sweep_share, time_limit=limit)

    def check_room(self, need: int) -> None:
        """:class:`StoreFull` when the runs, the sweeps' rows and ``need`` more bytes would pass
        ``max_store_bytes`` (the store's policy for runs aside: sweep rows are never evicted)."""
        cap, store = self.settings.store_cap, self.service.store
        size = (store.size if store is not None else 0) + self.admission.stored_bytes
        if size + need > cap.max_bytes:
            raise StoreFull(cap, store.count() if store is not None else 0, size, need)

    def rows_that_fit(self, sizes: list[int]) -> int:
        """How many of these rows (their sizes, bytes) fit under ``max_store_bytes`` now."""
        store = self.service.store
        room = self.settings.max_store_bytes - (store.size if store is not None else 0) - self.admission.stored_bytes
        fit = 0
        for size in sizes:
            room -= size
            if room < 0:
                break
            fit += 1
        return fit

    def run(self, sweep_id: str, base: dict, spec: SweepSpec) -> None:
        self.flush()
        sink = _Sink(self, sweep_id)
        try:
            self.admission.start(sweep_id)
            self.store.set_status(sweep_id, "running")
            with self.executor() as ex:
                res = run_sweep(base, spec, sink, executor=ex, progress=False)
            counts = ", ".join(f"{k} {v}" for k, v in sorted(res.statuses.items()))
            self.end(sweep_id, "done", f"{res.ran} runs in {res.wall_s:.2f} s: {counts}")
        except (StoreFull, StoreError) as e:  # the cap or the disk: what was stored stays
            self.end(sweep_id, "failed", f"stopped after {sink.n} of {len(spec)} runs (their rows are kept): {e}")
        except Exception as e:  # the service stopping, a lost scheduler
            self.end(sweep_id, "failed", f"{type(e).__name__}: {e}")
        finally:
            self.admission.release(sweep_id)

    def end(self, sweep_id: str, status: str, message: str) -> None:
        """Record a sweep's end; when the store cannot take it (its disk full), keep it here."""
        try:
            self.store.set_status(sweep_id, status, message)
        except StoreError as e:
            log.warning("sweep %s ended %s, not recorded in the store yet: %s", sweep_id, status, e)
            with self._lock:
                self.unwritten[sweep_id] = (status, message)

    def flush(self) -> None:
        """Write the ends the store could not take before (kept if it still cannot)."""
        with self._lock:
            waiting = dict(self.unwritten)
        for sweep_id, (status, message) in waiting.items():
            with contextlib.suppress(StoreError):
                self.store.set_status(sweep_id, status, message)
                with self._lock:
                    self.unwritten.pop(sweep_id, None)

    def state(self, sweep_id: str) -> dict | None:
        """A sweep's state from the store, with an end the store has not taken yet."""
        state = self.store.get(sweep_id)
        with self._lock:
            end = self.unwritten.get(sweep_id)
        if state is not None and end is not None:
            state["status"], state["message"] = end
        return state


def _manager_of(app: FastAPI) -> SweepManager:
    """The app's sweep manager, made at its first use (the lifespan's start, or a request)."""
    with _LOCK:
        m = getattr(app.state, "sweeps", None)
        if m is None:
            m = app.state.sweeps = SweepManager(app.state.settings, app.state.service)
    return m


async def get_sweeps(request: Request) -> SweepManager:
    """The app's sweep manager (a dependency of the routes)."""
    return _manager_of(request.app)


Sweeps = Annotated[SweepManager, Depends(get_sweeps)]
_LOCK = threading.Lock()
ROW_ESTIMATE = 32  # bytes per column of a stored row, for the room a new sweep needs at least
_FIELDS = {"--grid": "grid", "--log-grid": "log_grid", "--sample": "sample", "--samples": "samples", "--seed": "seed"}


def _unprocessable(e: InputError):
    head, _, rest = str(e.field).partition(" ")
    loc = ["body", _FIELDS[head]] if head in _FIELDS else ["body", "settings", *str(e.field).split(".")]
    field = f"{_FIELDS.get(head, head)} {rest}".strip() if head in _FIELDS else None
    msg = (
        f"{field or '.'.join(map(str, loc[1:]))}: got {e.value!r}"
        + (f" ({e.reason})" if e.reason else "")
        + f"; allowed: {e.allowed}"
    )
    return error_response(422, [item(loc, "value_error", e.value, e.reason, e.allowed, msg=msg)])


def _check_limits(base: dict, spec: SweepSpec, settings: Settings) -> None:
    from nmkane_core.run.plan import resolve
    from nmkane_core.sweep.runner import _axis_values
    from nmkane_core.sweep.spec import apply_point

    limit, max_steps = settings.max_sweep_runs, settings.max_steps
    if len(spec) > limit:
        raise InputError(
            "--grid",
            f"{len(spec):,} runs",
            f"at most {limit:,} runs per sweep (NMKANE_MAX_SWEEP_RUNS)",
            "too many runs",
        )
    plan = resolve(base)
    dts, tfs = [plan.dt], [plan.t_final]
    for name, values in _axis_values(spec):
        for v in values:
            p = resolve(apply_point(base, {name: v}))
            dts.append(p.dt)
            tfs.append(p.t_final)
    steps = math.ceil(max(tfs) / min(dts) - 1e-9)
    if steps > max_steps:
        raise InputError(
            "--grid",
            f"{steps:,} steps",
            f"runs of at most {max_steps:,} steps (the service's max_steps)",
            "the sweep's longest run is too long",
        )


@router.post(
    "/api/sweeps",
    status_code=202,
    response_model=SweepCreated,
    operation_id="create_sweep",
    responses={
        400: error_doc("the body could not be read as text (e.g. not UTF-8)"),
        413: error_doc("request body larger than max_request_bytes"),
        415: error_doc("the body is not declared as JSON (Content-Type)"),
        422: error_doc("a bad specification, or a sweep over this service's limits"),
        503: error_doc(
            "max_sweeps sweeps already admitted (running plus queued); retry after Retry-After seconds "
            "(the running sweep's remaining runs × the measured seconds per run ÷ its workers)",
            headers={"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
        ),
        507: error_doc("the store is full (max_store_bytes, runs and sweep rows) or its disk is"),
    },
)
def create_sweep(body: SweepRequest, sweeps: Sweeps, settings: AppSettings):
    """Start a sweep; answers 202 with its id (fetch progress and rows with GET /api/sweeps/{id})."""
    from nmkane_core.sweep.runner import check_spec

    base = body.settings.model_dump(exclude_none=True)
    try:
        spec = sweep_spec(
            body.grid, body.log_grid, body.sample, body.samples, body.seed, max_points=settings.max_sweep_runs
        )
        check_spec(base, spec)
        _check_limits(base, spec, settings)
        columns = output_columns(spec.names, constraint_columns(base, spec))
    except InputError as e:
        return _unprocessable(e)
    sweep_id = secrets.token_urlsafe(12)
    if not sweeps.admission.admit(sweep_id, len(spec)):
        return _sweeps_full(settings.max_sweeps, sweeps.admission.retry_after())
    system = base.get("system") or system_names()[0]  # left out: the catalogue's first, as a run
    request = body.model_dump(mode="json")
    try:
        sweeps.check_room(len(orjson.dumps(request)) + ROW_ESTIMATE * len(columns))  # room for a row at least
        sweeps.store.create(sweep_id, system, len(spec), request, columns)
        sweeps.admission.stored(len(orjson.dumps(request)))
        sweeps.queue.submit(sweeps.run, sweep_id, base, spec)
    except BaseException:
        sweeps.admission.release(sweep_id)
        raise
    return JSONResponse(
        {"id": sweep_id, "status": "queued", "total": len(spec)},
        status_code=202,
        headers={"Location": f"/api/sweeps/{sweep_id}"},
    )


def _sweeps_full(max_sweeps: int, wait: int) -> JSONResponse:
    return error_response(
        503,
        [item([], "overloaded", None, f"{max_sweeps} sweeps already admitted", f"retry after {wait} s")],
        headers={"Retry-After": str(wait)},
    )


def _no_sweep(sweep_id: str):
    return not_found("sweep_id", sweep_id, "sweep", "POST /api/sweeps")


class _CSV(Response):
    media_type = "text/csv"  # the 200 documented as text/csv (as GET /api/runs/{id}.csv)


_ERROR_JSON = {"content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorResponse"}}}}


@router.get(
    "/api/sweeps/{sweep_id}.csv",
    operation_id="get_sweep_csv",
    response_class=_CSV,
    responses={
        404: {**_ERROR_JSON, "description": "no sweep with this id"},
        422: {**_ERROR_JSON, "description": "malformed id"},
    },
)
def get_sweep_csv(sweeps: Sweeps, sweep_id: str = SWEEP_ID):
    """The rows so far as CSV (the columns of ``nmkane sweep --out FILE.csv``)."""
    state = sweeps.state(sweep_id)
    if state is None:
        return _no_sweep(sweep_id)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(state["columns"])
    for r in sweeps.store.rows(sweep_id):
        w.writerow(
            ["" if r.get(c) is None else repr(r[c]) if isinstance(r.get(c), float) else r[c] for c in state["columns"]]
        )
    return _CSV(buf.getvalue(), headers={"Content-Disposition": f'attachment; filename="{sweep_id}.csv"'})


@router.get(
    "/api/sweeps/{sweep_id}",
    response_model=SweepState,
    operation_id="get_sweep",
    responses={404: error_doc("no sweep with this id")},
)
def get_sweep(
    sweeps: Sweeps,
    sweep_id: str = SWEEP_ID,
    offset: int = Query(0, ge=0, le=2**62, description="rows to skip"),
    limit: int = Query(1000, ge=1, le=10_000, description="rows to return"),
):
    """Status, progress (``done`` of ``total``) and the rows so far, in completion order."""
    sweeps.flush()
    state = sweeps.state(sweep_id)
    if state is None:
        return _no_sweep(sweep_id)
    return {**state, "rows": sweeps.store.rows(sweep_id, offset, limit), "offset": offset}
