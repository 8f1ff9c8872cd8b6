"""``GET /api/health`` (and ``/``, which sends a browser to the API's docs)."""

from __future__ import annotations

from fastapi import APIRouter, Request
from fastapi.responses import RedirectResponse

from ..deps import AppSettings, Service, Store
from ..models import Health

__all__ = ["router"]

router = APIRouter()


@router.get("/", include_in_schema=False)
def root():
    return RedirectResponse("/docs")


@router.get("/api/health", response_model=Health, operation_id="health")
def health(request: Request, svc: Service, store: Store, settings: AppSettings):
    return Health(
        status="ok",
        version=request.app.version,
        runs_stored=store.count(),
        runs_in_flight=svc.admitted,
        runs_running=svc.running,
        queue_limit=settings.queue_limit,
    )
