"""``GET /api/health`` (and ``/``, which sends a browser to the API's docs)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import RedirectResponse

from ..deps import AppSettings, Service, Store
from ..errors import error_doc
from ..models import Health

__all__ = ["router"]

router = APIRouter()


@router.get("/", include_in_schema=False)
def root():
    return RedirectResponse("/docs")


@router.get(
    "/api/health",
    response_model=Health,
    operation_id="health",
    responses={
        503: error_doc(
            "the run store cannot be read, or its last write failed and it still cannot be written "
            "(read-only, damaged, I/O error): the message names the file and what to do"
        )
    },
)
def health(request: Request, svc: Service, store: Store, settings: AppSettings):
    # a store that stopped taking writes answers 503 (a full disk does not: reads and deletes work)
    store.check_writable()
    sweeps_running, sweeps_queued, sweep_runs_pending = svc.sweeps.counts()
    return Health(
        status="ok",
        version=request.app.version,
        runs_stored=store.count(),
        runs_in_flight=svc.admitted,
        runs_running=svc.running,
        queue_limit=settings.queue_limit,
        sweeps_running=sweeps_running,
        sweeps_queued=sweeps_queued,
        sweep_runs_pending=sweep_runs_pending,
        sweep_runs_running=svc.sweeps.runs_running,
        max_sweeps=settings.max_sweeps,
        sweep_workers=settings.sweep_share,
    )
