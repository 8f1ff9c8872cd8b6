"""The REST face of nmkane (FastAPI).

    GET  /api/health              liveness, stored runs, runs in flight
    GET  /api/systems             systems, parameters, models, constraints, integrators, limits
    POST /api/runs                body = run settings (JSON) -> 201 + run result document
    GET  /api/runs                recent runs (summaries), ?limit=&offset=
    GET  /api/runs/{id}           a stored run document
    GET  /api/runs/{id}.csv       the same as CSV

Simulations are CPU work: they run in a bounded worker pool, never on the event loop;
past ``queue_limit`` admitted runs the service answers 503 with ``Retry-After``.  Run
documents are serialized once with orjson straight from numpy and stored compressed.
"""

from __future__ import annotations

import asyncio
import contextlib
import csv
import io
import math
import secrets
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import orjson
from fastapi import Depends, FastAPI, Query, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse, PlainTextResponse, Response
from starlette.exceptions import HTTPException as StarletteHTTPException

from nmkane_core.errors import InputError
from nmkane_core.schema import RunResult, RunSettings
from nmkane_core.simulate import catalog, resolve, simulate
from nmkane_core.system import get_system, system_names

from .config import Settings
from .store import RunStore

__all__ = ["create_app"]

ERROR_RESPONSES = {
    400: {"description": "the body is not parseable JSON"},
    422: {"description": "invalid settings: the field path, the value given and what is allowed"},
    413: {"description": "request body too large"},
    503: {"description": "too many runs in progress; retry after the Retry-After seconds"},
}


def _plain(value):
    """A JSON-safe copy of an offending input value (non-finite numbers as strings)."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    return repr(value)


def _error(status: int, detail, headers=None) -> JSONResponse:
    return JSONResponse(status_code=status, content={"detail": detail}, headers=headers)


class _Service:
    """Worker pool, admission control and the run store of one app."""

    def __init__(self, settings: Settings):
        self.settings = settings
        self._lock = threading.Lock()
        self.admitted = 0
        self.store = None
        self.pool = None
        self.open()

    def open(self) -> None:
        """(Re)open the store and the pool: an app can go through several lifespans."""
        with self._lock:
            if self.store is None:
                self.store = RunStore(self.settings.database)
            if self.pool is None:
                self.pool = ThreadPoolExecutor(max_workers=self.settings.max_concurrent_runs,
                                               thread_name_prefix="run")

    def admit(self) -> bool:
        self.open()
        with self._lock:
            if self.admitted >= self.settings.queue_limit:
                return False
            self.admitted += 1
            return True

    def release(self) -> None:
        with self._lock:
            self.admitted -= 1

    def check_limits(self, plan) -> None:
        s = self.settings
        if not plan.integrator.adaptive:
            steps = math.ceil(plan.t_final / plan.dt - 1e-9)
            if steps > s.max_steps:
                raise InputError("dt", plan.dt, f"t_final/dt ≤ {s.max_steps:,} steps on this service "
                                 f"(dt ≥ {plan.t_final / s.max_steps:.3g} s for t_final = {plan.t_final:g} s)",
                                 f"{steps:,} steps")
            rows = steps // plan.every + 2
            if rows > s.max_rows:
                raise InputError("every", plan.every, f"an integer ≥ {math.ceil(steps / s.max_rows)} "
                                 f"(at most {s.max_rows:,} output rows on this service)", f"{rows:,} rows")

    def execute(self, settings: RunSettings) -> tuple[str, bytes]:
        plan = resolve(settings)
        self.check_limits(plan)
        run = simulate(plan, progress=False, time_limit=self.settings.max_wall_time_s)
        run_id = secrets.token_urlsafe(16)
        doc = {"id": run_id, "system": run.system, "settings": run.settings, "t": run.t, "state": run.state,
               "energy": run.energy, "violation": run.violation, "summary": run.summary}
        body = orjson.dumps(doc, option=orjson.OPT_SERIALIZE_NUMPY)
        self.store.add(run_id, run.system, run.status, run.settings, run.summary, body)
        return run_id, body

    def close(self) -> None:
        """Finish the runs in flight (each is stored before its 201), then release."""
        with self._lock:
            pool, store, self.pool, self.store = self.pool, self.store, None, None
        if pool is not None:
            pool.shutdown(wait=True)
        if store is not None:
            store.close()


class _BodyLimit:
    """Pure ASGI middleware: refuse bodies over ``limit`` bytes with 413, streamed or not."""

    def __init__(self, app, limit: int):
        self.app, self.limit = app, limit

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        headers = dict(scope.get("headers") or [])
        length = headers.get(b"content-length")
        too_big = JSONResponse(status_code=413, content={"detail": [{
            "loc": ["body"], "msg": f"request body larger than {self.limit} bytes", "type": "too_large"}]})
        if length is not None:
            try:
                if int(length) > self.limit:
                    return await too_big(scope, receive, send)
            except ValueError:
                return await _error(400, "bad Content-Length")(scope, receive, send)
        seen = 0

        async def limited():
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:
                    raise _TooLarge()
            return message

        try:
            await self.app(scope, limited, send)
        except _TooLarge:
            await too_big(scope, receive, send)


class _TooLarge(Exception):
    pass


def create_app(settings: Settings | None = None) -> FastAPI:
    """The FastAPI app (one per settings; tests build one against a temporary database)."""
    settings = settings or Settings()

    svc = _Service(settings)

    @contextlib.asynccontextmanager
    async def lifespan(app: FastAPI):
        if settings.warm_kernels:       # load (or compile once) the kernels before serving
            await asyncio.get_running_loop().run_in_executor(svc.pool, _warm)
        svc.open()
        try:
            yield
        finally:
            svc.close()

    app = FastAPI(title="nmkane", version="0.1.0", lifespan=lifespan,
                  description="Nonminimal Kane's equations (Bajodah, Hodges & Chen 2005): run simulations "
                              "of the Appell–Hamel mechanism and the sliding particle, and fetch them by id.")
    app.state.svc = svc
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(CORSMiddleware, allow_origins=list(settings.cors_origins),
                           allow_methods=["GET", "POST"], allow_headers=["content-type"])
    app.add_middleware(_BodyLimit, limit=settings.max_request_bytes)

    def service(request: Request) -> _Service:
        return request.app.state.svc

    @app.exception_handler(RequestValidationError)
    async def _validation(request: Request, exc: RequestValidationError):
        detail = [{"loc": list(e.get("loc", ())), "msg": e.get("msg", ""), "type": e.get("type", ""),
                   "input": _plain(e.get("input"))} for e in exc.errors()]
        return _error(422, detail)

    @app.exception_handler(StarletteHTTPException)
    async def _http_error(request: Request, exc: StarletteHTTPException):
        headers = dict(exc.headers or {})
        if exc.status_code == 405:      # list every method of every route on this path
            methods = set()
            for route in app.routes:
                match = getattr(route, "path_regex", None)
                if match is not None and match.match(request.url.path) and getattr(route, "methods", None):
                    methods |= set(route.methods)
            headers["Allow"] = ", ".join(sorted(methods))
        return _error(exc.status_code, exc.detail, headers=headers)

    @app.exception_handler(InputError)
    async def _input_error(request: Request, exc: InputError):
        loc = ["body", *exc.field.split(".")]
        return _error(422, [{"loc": loc, "msg": str(exc), "type": "value_error", "input": _plain(exc.value),
                             "allowed": exc.allowed, "reason": exc.reason}])

    @app.get("/api/health")
    def health(svc: _Service = Depends(service)):
        svc.open()
        return {"status": "ok", "runs_stored": svc.store.count(), "runs_in_flight": svc.admitted}

    @app.get("/api/systems")
    def systems(svc: _Service = Depends(service)):
        data = catalog()
        data["service_limits"] = svc.settings.limits()
        return data

    @app.post("/api/runs", status_code=201, response_model=RunResult, responses=ERROR_RESPONSES)
    async def create_run(body: RunSettings, svc: _Service = Depends(service)):
        if not svc.admit():
            return _error(503, f"{svc.settings.queue_limit} runs already admitted; retry shortly",
                          headers={"Retry-After": "1"})
        try:
            run_id, doc = await asyncio.get_running_loop().run_in_executor(svc.pool, svc.execute, body)
        finally:
            svc.release()
        return Response(doc, status_code=201, media_type="application/json",
                        headers={"Location": f"/api/runs/{run_id}"})

    @app.get("/api/runs")
    def list_runs(limit: int = Query(20, ge=1, le=200), offset: int = Query(0, ge=0, le=10**9),
                  svc: _Service = Depends(service)):
        svc.open()
        return {"runs": svc.store.list(limit, offset), "limit": limit, "offset": offset}

    @app.get("/api/runs/{run_id}.csv", response_class=PlainTextResponse,
             responses={404: {"description": "no such run"}})
    def run_csv(run_id: str, svc: _Service = Depends(service)):
        svc.open()
        doc = svc.store.document(run_id)
        if doc is None:
            return _error(404, f"no run with id {run_id!r}")
        return PlainTextResponse(_to_csv(orjson.loads(doc)), media_type="text/csv",
                                 headers={"Content-Disposition": f'attachment; filename="{run_id}.csv"'})

    @app.get("/api/runs/{run_id}", response_model=RunResult, responses={404: {"description": "no such run"}})
    def get_run(run_id: str, svc: _Service = Depends(service)):
        svc.open()
        doc = svc.store.document(run_id)
        if doc is None:
            return _error(404, f"no run with id {run_id!r}")
        return Response(doc, media_type="application/json")

    return app


def _warm() -> None:
    for name in system_names():
        system = get_system(name)
        for variant in system.variants:
            system.kernel(variant)
    simulate({"system": "appell-hamel", "t_final": 0.1}, progress=False)


def _to_csv(doc: dict) -> str:
    cols = {"t": doc["t"], **doc["state"]}
    if doc.get("energy") is not None:
        cols["energy"] = doc["energy"]
    cols.update({f"violation_{k}": v for k, v in doc["violation"].items()})
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    w.writerows(zip(*[np.asarray(c, float).tolist() for c in cols.values()]))
    return buf.getvalue()
