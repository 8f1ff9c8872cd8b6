"""Sweeps over REST: many runs in the background, progress and rows fetched by id.

    POST /api/sweeps              body = {settings, grid, log_grid, sample, samples, seed}
                                  (the texts of ``nmkane sweep``'s options) -> 202 + id
    GET  /api/sweeps/{id}         status, progress and the rows so far (?offset=&limit=)
    GET  /api/sweeps/{id}.csv     the rows as CSV (the columns of ``nmkane sweep --out``)

A sweep is checked before the 202 (every varied value against the system; its size against
the setting ``max_sweep_runs``, ``NMKANE_MAX_SWEEP_RUNS``, default 10,000; its longest run
against the service's ``max_steps``): bad input answers 422 naming the field.  Sweeps run one
at a time, their batches on the service's worker pool, or on the Dask scheduler of the
setting ``dask_scheduler``, ``NMKANE_DASK_SCHEDULER`` (``tcp://HOST:PORT``; its workers need
nmkane installed).  Rows are
stored in the service's SQLite file (tables ``sweeps`` and ``sweep_rows``), batch by batch,
each batch in one transaction.

A sweep left ``queued`` or ``running`` by a process that is gone (killed, the machine
restarted) is marked ``interrupted`` when the service starts; see :mod:`backend.sweep_store`.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import csv
import io
import math
import secrets
import threading
from typing import Annotated

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
from .sweep_store import SweepStore, owner_alive, process_owner

__all__ = ["SweepManager", "SweepRequest", "SweepStore", "owner_alive", "process_owner", "router"]


@contextlib.asynccontextmanager
async def _lifespan(app):
    """At the service's start: open the sweep store, so sweeps a stopped service left running
    are marked ``interrupted`` before the first request."""
    if getattr(app, "state", None) is not None and hasattr(app.state, "settings"):
        _manager_of(app)
    yield


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
    """run_sweep's output: rows into the store (``done`` is empty: a REST sweep starts fresh)."""

    def __init__(self, store: SweepStore, sweep_id: str):
        self.store, self.id, self.n = store, sweep_id, 0
        self.done: set = set()

    def write(self, rows):
        clean = [
            {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in r.items()} for r in rows
        ]
        self.store.add_rows(self.id, self.n, clean)
        self.n += len(rows)


class PoolExecutor(_Executor):
    """Batches on the service's thread pool (the compiled loops release the GIL)."""

    name = "service-pool"

    def __init__(self, pool: cf.ThreadPoolExecutor, workers: int, **kw):
        super().__init__(**kw)
        self.pool, self.workers = pool, workers

    def rows(self, base, points, size):
        from nmkane_core.sweep.executors import _batches

        pending: set = set()
        it = _batches(points, size)

        def fill():
            for batch in it:
                pending.add(self.pool.submit(run_batch, self.systems, base, batch, (), self.time_limit))
                if len(pending) >= self.workers:
                    break

        fill()
        while pending:
            done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
            for f in done:
                pending.discard(f)
                yield f.result()
            fill()


class SweepManager:
    """The store and the one thread that runs sweeps in order."""

    def __init__(self, settings: Settings, service: RunService):
        self.settings, self.service = settings, service
        self.store = SweepStore(settings.database)
        self.queue = cf.ThreadPoolExecutor(max_workers=1, thread_name_prefix="nmkane-sweep")

    def executor(self):
        limit = self.settings.max_wall_time_s
        if self.settings.dask_scheduler is not None:
            from nmkane_core.sweep.executors import DaskExecutor

            return DaskExecutor(self.settings.dask_scheduler, time_limit=limit)
        if self.service.pool is None:
            self.service.start()
        pool = self.service.pool
        if pool is None:  # stopped meanwhile
            raise RuntimeError("the run service is stopping")
        return PoolExecutor(pool, self.settings.max_concurrent_runs, time_limit=limit)

    def run(self, sweep_id: str, base: dict, spec: SweepSpec) -> None:
        self.store.set_status(sweep_id, "running")
        try:
            with self.executor() as ex:
                res = run_sweep(base, spec, _Sink(self.store, sweep_id), executor=ex, progress=False)
            counts = ", ".join(f"{k} {v}" for k, v in sorted(res.statuses.items()))
            self.store.set_status(sweep_id, "done", f"{res.ran} runs in {res.wall_s:.2f} s: {counts}")
        except Exception as e:  # the service stopping, a lost scheduler
            self.store.set_status(sweep_id, "failed", f"{type(e).__name__}: {e}")


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
    system = base.get("system") or system_names()[0]  # left out: the catalogue's first, as a run
    sweeps.store.create(sweep_id, system, len(spec), body.model_dump(mode="json"), columns)
    sweeps.queue.submit(sweeps.run, sweep_id, base, spec)
    return JSONResponse(
        {"id": sweep_id, "status": "queued", "total": len(spec)},
        status_code=202,
        headers={"Location": f"/api/sweeps/{sweep_id}"},
    )


def _no_sweep(sweep_id: str):
    return not_found("sweep_id", sweep_id, "sweep", "POST /api/sweeps")


@router.get(
    "/api/sweeps/{sweep_id}.csv",
    operation_id="get_sweep_csv",
    responses={404: {"description": "no sweep with this id"}},
)
def get_sweep_csv(sweeps: Sweeps, sweep_id: str = SWEEP_ID):
    """The rows so far as CSV (the columns of ``nmkane sweep --out FILE.csv``)."""
    state = sweeps.store.get(sweep_id)
    if state is None:
        return _no_sweep(sweep_id)
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(state["columns"])
    for r in sweeps.store.rows(sweep_id):
        w.writerow(
            ["" if r.get(c) is None else repr(r[c]) if isinstance(r.get(c), float) else r[c] for c in state["columns"]]
        )
    return Response(
        buf.getvalue(), media_type="text/csv", headers={"Content-Disposition": f'attachment; filename="{sweep_id}.csv"'}
    )


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
    state = sweeps.store.get(sweep_id)
    if state is None:
        return _no_sweep(sweep_id)
    return {**state, "rows": sweeps.store.rows(sweep_id, offset, limit), "offset": offset}
