"""The REST face of nmkane (FastAPI); OpenAPI docs at ``/docs``.

    GET  /api/health              liveness, stored runs, runs in flight
    GET  /api/systems             systems, parameters, models, constraints, integrators, limits
    POST /api/runs                body = run settings (JSON) -> 201 + run result document
    GET  /api/runs                recent runs (summaries), ?limit=&offset=&system=&status=
    GET  /api/runs/{id}           a stored run document
    GET  /api/runs/{id}.csv       the same as CSV (the CLI's CSV)
    DELETE /api/runs/{id}         delete a stored run (204)
    POST /api/sweeps, GET /api/sweeps/{id}[.csv]   sweeps (backend.sweeps)

Every request must name an allowed host (``Host``: loopback names, the bound address and
``--allow-host`` names; 400 otherwise); with a token configured (``nmkane serve`` on a
non-loopback address), requests that write, and reads of the stored runs and sweeps, need
``Authorization: Bearer <token>`` (401).
A full store refuses new runs with 507 (or evicts the oldest, when configured so).

:func:`create_app` is the one place that builds the app: the settings and the run service
go into ``app.state`` (the routes get them through :mod:`backend.deps`), then the routers of
:mod:`backend.routes`, the error handlers of :mod:`backend.errors` and the ASGI layers of
:mod:`backend.middleware` and :mod:`backend.guard`.
"""

from __future__ import annotations

import asyncio
import contextlib
import sys
from importlib import metadata

from fastapi import FastAPI
from fastapi_offline import FastAPIOffline

from nmkane_core.access import HostAllowList

from .config import Settings
from .errors import install_error_handlers
from .guard import HostCheck, TokenCheck
from .middleware import BodySizeLimit, HeadAsGet
from .routes import ROUTERS
from .service import RunService

__all__ = ["create_app", "VERSION"]

try:
    VERSION = metadata.version("nmkane")
except metadata.PackageNotFoundError:  # running from a source tree without install
    VERSION = "0.1.0"


def description() -> str:
    """The OpenAPI description, naming the systems registered when the app is made."""
    from nmkane_core.run.registry import get_system, system_names

    systems = "; ".join(f"`{n}` ({get_system(n).title or n})" for n in system_names())
    return (
        "Nonminimal Kane's equations (Bajodah, Hodges & Chen 2005) as a service: run simulations of "
        f"any registered system — here {systems} — and fetch them later by id. GET /api/systems lists "
        "each one's parameters, variants, constraints and defaults; limits are listed there under "
        '`service_limits`. Every error answers `{"detail": [{loc, field, value, reason, allowed, msg, type}]}`.'
    )


def create_app(settings: Settings | None = None) -> FastAPI:
    """The FastAPI app (one per settings; tests build one against a temporary database)."""
    settings = settings if settings is not None else Settings()
    app = FastAPIOffline(  # /docs served with local assets: works offline
        title="nmkane", version=VERSION, description=description(), lifespan=_lifespan
    )
    app.state.settings = settings
    app.state.service = RunService(settings)
    install_error_handlers(app)
    for router in ROUTERS:
        app.include_router(router)
    _add_layers(app, settings)
    return app


def _add_layers(app: FastAPI, settings: Settings) -> None:
    """The ASGI layers around the routes, innermost first (the Host check is outermost)."""
    if settings.cors_origins:
        from fastapi.middleware.cors import CORSMiddleware

        app.add_middleware(
            CORSMiddleware,
            allow_origins=list(settings.cors_origins),
            allow_methods=["GET", "POST"],
            allow_headers=["content-type"],
            expose_headers=["location", "retry-after"],
        )
    app.add_middleware(BodySizeLimit, limit=settings.max_request_bytes)
    app.add_middleware(HeadAsGet)
    if settings.token:
        app.add_middleware(TokenCheck, token=settings.token)
    app.add_middleware(HostCheck, rule=HostAllowList.of(extra=settings.allowed_hosts))


@contextlib.asynccontextmanager
async def _lifespan(app: FastAPI):
    """Start the run service (and warm the kernels, when the settings say so); stop it at the end."""
    svc: RunService = app.state.service
    svc.start()
    if app.state.settings.warm_kernels:
        await _warm(svc)
    try:
        yield
    finally:
        await asyncio.get_running_loop().run_in_executor(None, svc.stop)


def _report(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


async def _warm(svc: RunService) -> None:
    """Load what a request naming only a system runs before the first is served; the other
    variants load in the background."""
    _report("nmkane: preparing every system's model (a first start derives each and compiles its C functions)")
    first, later = svc.warm_steps()
    await asyncio.get_running_loop().run_in_executor(svc.pool, svc.warm, _report, first)
    if svc.warm_interrupted:  # a stop asked during the warm-up (serve stops the service next)
        return
    _report("nmkane: the service is ready; the other variants load in the background")
    svc.warm_in_background(later, _report, title="the other variants")
