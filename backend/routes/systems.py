"""``GET /api/systems``: what can be run, and the limits of the library and of this service."""

from __future__ import annotations

from functools import lru_cache

from fastapi import APIRouter

from nmkane_core.run.catalog import catalog

from ..config import LIMIT_DESCRIPTIONS
from ..deps import AppSettings
from ..models import Catalog

__all__ = ["router"]

router = APIRouter()


@router.get("/api/systems", response_model=Catalog, operation_id="systems")
def systems(settings: AppSettings):
    """Systems, parameters (defaults, ranges, units), models or formulations, constraint names,
    integrators, projections, and the limits of the library and of this service."""
    return {
        **_catalog(),
        "service_limits": settings.limits(),
        "service_limit_descriptions": dict(LIMIT_DESCRIPTIONS),
    }


def _catalog() -> dict:
    from nmkane_core.run.registry import generation

    return _catalog_at(generation())


@lru_cache(maxsize=4)
def _catalog_at(_generation: int) -> dict:  # refreshed when systems are registered later
    return catalog()
