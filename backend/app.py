"""The REST face of nmkane (FastAPI); OpenAPI docs at ``/docs``.

    GET  /api/health              liveness, stored runs, runs in flight
    GET  /api/systems             systems, parameters, models, constraints, integrators, limits
    POST /api/runs                body = run settings (JSON) -> 201 + run result document
    GET  /api/runs                recent runs (summaries), ?limit=&offset=&system=&status=
    GET  /api/runs/{id}           a stored run document
    GET  /api/runs/{id}.csv       the same as CSV (the CLI's CSV)
    DELETE /api/runs/{id}         delete a stored run (204)

Every request must name an allowed host (``Host``: loopback names, the bound address and
``--allow-host`` names; 400 otherwise); with a token configured (``nmkane serve`` on a
non-loopback address), requests that write need ``Authorization: Bearer <token>`` (401).
A full store refuses new runs with 507 (or evicts the oldest, when configured so).

Route functions are thin: the work is in :class:`backend.service.RunService` (worker
pool, admission, limits, encoding) and :class:`backend.store.RunStore` (SQLite).  Run
documents are encoded once, when the run finishes, and served as stored bytes; the
OpenAPI schema still documents them as the core's ``RunResult``.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import sys
from functools import lru_cache
from importlib import metadata
from typing import Any

import numpy as np
import orjson
from fastapi import Depends, FastAPI, Path, Query
from fastapi.responses import JSONResponse, RedirectResponse, Response, StreamingResponse
from fastapi_offline import FastAPIOffline
from starlette.exceptions import HTTPException as StarletteHTTPException

from nmkane_core.run.catalog import catalog
from nmkane_core.run.result import Run
from nmkane_core.schema import RunResult

from .config import LIMIT_DESCRIPTIONS, Settings
from .errors import ErrorResponse, error_response, install_error_handlers, item
from .guard import HostCheck, TokenCheck, allowed_host_names
from .models import STATUSES, Catalog, Health, RunList, RunSettings
from .service import RunService
from .sweeps import router as sweeps_router

__all__ = ["create_app"]

try:
    VERSION = metadata.version("nmkane")
except metadata.PackageNotFoundError:  # running from a source tree without install
    VERSION = "0.1.0"

RUN_ID = Path(description="the run's id, as returned by POST /api/runs", min_length=1, max_length=64)

_ERR: dict[str, Any] = {"model": ErrorResponse}
POST_RESPONSES: dict[int | str, dict[str, Any]] = {
    201: {
        "description": "the run result document (also for runs that ended singular, diverged or timeout)",
        "links": {
            "GetRun": {
                "operationId": "get_run",
                "parameters": {"run_id": "$response.body#/id"},
                "description": "the stored run",
            },
            "GetRunCsv": {
                "operationId": "get_run_csv",
                "parameters": {"run_id": "$response.body#/id"},
                "description": "the stored run as CSV",
            },
        },
    },
    400: {**_ERR, "description": "the body could not be read as text (e.g. not UTF-8)"},
    413: {**_ERR, "description": "request body larger than max_request_bytes"},
    415: {**_ERR, "description": "the body is not declared as JSON (Content-Type)"},
    422: {**_ERR, "description": "invalid settings: field path, value, reason and what is allowed"},
    507: {
        **_ERR,
        "description": "the run store is full (max_stored_runs or max_store_bytes); delete runs or raise the cap",
    },
    503: {
        **_ERR,
        "description": "queue_limit runs already admitted; retry after Retry-After seconds",
        "headers": {"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
    },
}
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: {**_ERR, "description": "no run with this id"},
    422: {**_ERR, "description": "malformed id"},
}
_ERR_JSON = {"content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorResponse"}}}}
NOT_FOUND_CSV: dict[int | str, dict[str, Any]] = {
    404: {**_ERR_JSON, "description": "no run with this id"},
    422: {**_ERR_JSON, "description": "malformed id"},
}


class JSONBytes(JSONResponse):
    """JSON already encoded (orjson); documented by the route's ``response_model``."""

    def render(self, content) -> bytes:
        return content


class CSVResponse(Response):
    media_type = "text/csv"


class _BodyTooLarge(StarletteHTTPException):
    def __init__(self):
        super().__init__(status_code=413, detail="request body too large")


class _BodySizeLimit:
    """Pure ASGI: refuse request bodies over ``limit`` bytes with 413 (in the one error shape).

    A declared Content-Length over the limit is refused before anything is read; a body
    without one (chunked) is counted as it is read, and reading stops past the limit.
    (FastAPI's own ``max_body_size`` answers such requests in plain text.)
    """

    def __init__(self, app, limit: int):
        self.app, self.limit = app, limit

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        for name, value in scope.get("headers") or ():
            if name == b"content-length" and value.isdigit() and int(value) > self.limit:
                response = error_response(413, [_too_large(int(value), self.limit)])
                return await response(scope, receive, send)
        seen = 0

        async def counted():
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:
                    raise _BodyTooLarge()  # FastAPI passes HTTPExceptions to the handlers
            return message

        return await self.app(scope, counted, send)


class _HeadAsGet:
    """Pure ASGI: answer HEAD on every GET route like GET, without the body (FastAPI's routes
    answer only the methods they declare; HTTP says a GET resource also answers HEAD)."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "HEAD":
            return await self.app(scope, receive, send)

        async def headers_only(message):
            if message["type"] == "http.response.body":
                if message.get("more_body", False):
                    return
                message = {"type": "http.response.body", "body": b"", "more_body": False}
            await send(message)

        return await self.app({**scope, "method": "GET"}, receive, headers_only)


def _too_large(size, limit: int) -> dict:
    return item(["body"], "too_large", size, "request body too large", f"at most {limit:,} bytes")


def _catalog() -> dict:
    from nmkane_core.run.registry import generation

    return _catalog_at(generation())


@lru_cache(maxsize=4)
def _catalog_at(_generation: int) -> dict:  # refreshed when systems are registered later
    return catalog()


def _iso(ts: float) -> str:
    return dt.datetime.fromtimestamp(ts, dt.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _csv_chunks(doc: bytes, rows_per_chunk: int = 5000):
    """The CLI's CSV (``Run.to_csv``) of a stored document, in chunks of rows.

    Each chunk is ``Run.to_csv`` of a slice (header kept on the first only), so the text is
    exactly the CLI's, and a long run streams without holding the GIL for seconds.
    """
    d = orjson.loads(doc)
    arr = lambda v: np.asarray(v, dtype=float)  # noqa: E731
    t = arr(d["t"])
    state = {k: arr(v) for k, v in d["state"].items()}
    energy = None if d["energy"] is None else arr(d["energy"])
    violation = {k: arr(v) for k, v in d["violation"].items()}
    del d
    for start in range(0, max(t.size, 1), rows_per_chunk):
        part = slice(start, start + rows_per_chunk)
        text = Run(
            system="",
            settings={},
            t=t[part],
            state={k: v[part] for k, v in state.items()},
            energy=None if energy is None else energy[part],
            violation={k: v[part] for k, v in violation.items()},
            summary={},
        ).to_csv()
        yield text if start == 0 else text.split("\n", 1)[1]


def create_app(settings: Settings | None = None) -> FastAPI:
    """The FastAPI app (one per settings; tests build one against a temporary database)."""
    settings = settings if settings is not None else Settings()
    svc = RunService(settings)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        svc.start()
        if settings.warm_kernels:

            def report(line: str) -> None:
                print(line, file=sys.stderr, flush=True)

            report("nmkane: preparing the kernels (the first start after install compiles them)")
            first, later = svc.warm_steps()
            await asyncio.get_running_loop().run_in_executor(svc.pool, svc.warm, report, first)
            report(
                "nmkane: the service is ready; the loops with a post-step projection load in the "
                "background (a first start after install compiles them, one to two minutes)"
            )
            svc.warm_in_background(later, report)
        try:
            yield
        finally:
            await asyncio.get_running_loop().run_in_executor(None, svc.stop)

    app = FastAPIOffline(  # /docs served with local assets: works offline
        title="nmkane",
        version=VERSION,
        lifespan=lifespan,
        description="Nonminimal Kane's equations (Bajodah, Hodges & Chen 2005) as a service: run "
        "simulations of the Appell–Hamel mechanism and the sliding particle, and fetch "
        "them later by id. Limits are listed in GET /api/systems under `service_limits`. "
        'Every error answers `{"detail": [{loc, field, value, reason, allowed, msg, type}]}`.',
    )
    app.state.settings = settings
    app.state.service = svc
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=list(settings.cors_origins),
            allow_methods=["GET", "POST"],
            allow_headers=["content-type"],
            expose_headers=["location", "retry-after"],
        )
    install_error_handlers(app)
    app.include_router(sweeps_router)
    app.add_middleware(_BodySizeLimit, limit=settings.max_request_bytes)
    app.add_middleware(_HeadAsGet)
    if settings.token:
        app.add_middleware(TokenCheck, token=settings.token)
    app.add_middleware(HostCheck, allowed=allowed_host_names(extra=settings.allowed_hosts))  # outermost

    async def service() -> RunService:
        if svc.pool is None:  # an app used without its lifespan (a bare TestClient)
            svc.start()
        return svc

    @app.get("/", include_in_schema=False)
    def root():
        return RedirectResponse("/docs")

    @app.get("/api/health", response_model=Health, operation_id="health")
    def health(svc: RunService = Depends(service)):
        return Health(
            status="ok",
            version=VERSION,
            runs_stored=svc.opened_store().count(),
            runs_in_flight=svc.admitted,
            runs_running=svc.running,
            queue_limit=settings.queue_limit,
        )

    @app.get("/api/systems", response_model=Catalog, operation_id="systems")
    def systems():
        """Systems, parameters (defaults, ranges, units), models or formulations, constraint names,
        integrators, projections, and the limits of the library and of this service."""
        return {
            **_catalog(),
            "service_limits": settings.limits(),
            "service_limit_descriptions": dict(LIMIT_DESCRIPTIONS),
        }

    @app.post(
        "/api/runs",
        status_code=201,
        response_model=RunResult,
        response_class=JSONBytes,
        responses=POST_RESPONSES,
        operation_id="create_run",
    )
    async def create_run(body: RunSettings, svc: RunService = Depends(service)):
        """Run a simulation and store it; answers 201 with the run result document and its
        `Location`. Omitted fields take the system's defaults."""
        if not svc.admit():
            wait = svc.retry_after()
            return error_response(
                503,
                [
                    item(
                        [], "overloaded", None, f"{settings.queue_limit} runs already admitted", f"retry after {wait} s"
                    )
                ],
                headers={"Retry-After": str(wait)},
            )
        try:
            run_id, doc = await svc.run(body)
        finally:
            svc.release()
        return JSONBytes(doc, status_code=201, headers={"Location": f"/api/runs/{run_id}"})

    @app.get("/api/runs", response_model=RunList, response_class=JSONBytes, operation_id="list_runs")
    def list_runs(
        limit: int = Query(20, ge=1, le=200, description="runs per page"),
        offset: int = Query(0, ge=0, le=2**62, description="runs to skip (newest first)"),
        system: str | None = Query(None, max_length=64, description="only runs of this system"),
        status: STATUSES | None = Query(None, description="only runs with this status"),
        svc: RunService = Depends(service),
    ):
        """Recent runs, newest first: id, time, system, status, resolved settings and summary."""
        runs = svc.opened_store().list(limit, offset, system, status)
        for r in runs:
            r["created"] = _iso(r["created"])
        return JSONBytes(
            orjson.dumps(
                {"runs": runs, "total": svc.opened_store().count(system, status), "limit": limit, "offset": offset}
            )
        )

    @app.get("/api/runs/{run_id}.csv", response_class=CSVResponse, responses=NOT_FOUND_CSV, operation_id="get_run_csv")
    def get_run_csv(run_id: str = RUN_ID, svc: RunService = Depends(service)):
        """The stored run as CSV: t, the state, energy, violation_<constraint> (one row per output step)."""
        doc = svc.opened_store().document(run_id)
        if doc is None:
            return _not_found(run_id)
        return StreamingResponse(
            _csv_chunks(doc),
            media_type=CSVResponse.media_type,
            headers={"Content-Disposition": f'attachment; filename="{run_id}.csv"'},
        )

    @app.get(
        "/api/runs/{run_id}",
        response_model=RunResult,
        response_class=JSONBytes,
        responses=NOT_FOUND,
        operation_id="get_run",
    )
    def get_run(run_id: str = RUN_ID, svc: RunService = Depends(service)):
        """The stored run result document, exactly as POST /api/runs answered it."""
        doc = svc.opened_store().document(run_id)
        if doc is None:
            return _not_found(run_id)
        return JSONBytes(doc)

    @app.delete(
        "/api/runs/{run_id}",
        status_code=204,
        responses={**NOT_FOUND, 401: {**_ERR, "description": "an access token is asked for and was missing or wrong"}},
        operation_id="delete_run",
    )
    def delete_run(run_id: str = RUN_ID, svc: RunService = Depends(service)):
        """Delete a stored run (its document, CSV and listing entry)."""
        if not svc.opened_store().delete(run_id):
            return _not_found(run_id)
        return Response(status_code=204)

    return app


def _not_found(run_id: str):
    return error_response(
        404, [item(["path", "run_id"], "not_found", run_id, "no run with this id", "an id returned by POST /api/runs")]
    )
