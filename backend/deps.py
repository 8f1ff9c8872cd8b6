"""What the routes depend on, as FastAPI dependencies (``Depends``): the app's settings, its
run service (worker pool, admission, limits) and its run store.

Each app holds its own (``create_app(settings)`` puts them in ``app.state``), so tests build
apps against temporary databases side by side.  Use them as annotations::

    @router.get("/api/health")
    def health(svc: Service, settings: AppSettings): ...
"""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Request

from .config import Settings
from .service import RunService
from .store import RunStore

__all__ = ["AppSettings", "Service", "Store", "get_service", "get_settings", "get_store"]


async def get_settings(request: Request) -> Settings:
    """The app's settings."""
    return request.app.state.settings


async def get_service(request: Request) -> RunService:
    """The app's run service, started (an app used without its lifespan — a bare TestClient —
    starts it on its first request)."""
    svc: RunService = request.app.state.service
    if svc.pool is None:
        svc.start()
    return svc


async def get_store(svc: Annotated[RunService, Depends(get_service)]) -> RunStore:
    """The run store of the started service."""
    return svc.opened_store()


AppSettings = Annotated[Settings, Depends(get_settings)]
Service = Annotated[RunService, Depends(get_service)]
Store = Annotated[RunStore, Depends(get_store)]
