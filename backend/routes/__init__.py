"""The REST API's routes, one router per resource: :mod:`.health` (``/``, ``/api/health``),
:mod:`.systems` (``/api/systems``), :mod:`.runs` (``/api/runs``) and the sweeps
(``/api/sweeps``, :mod:`backend.sweeps`, where the sweeps' manager lives too).

:data:`ROUTERS` is the order ``create_app`` includes them in (the order of the OpenAPI
document's paths)."""

from __future__ import annotations

from ..sweeps import router as sweeps
from .health import router as health
from .runs import router as runs
from .systems import router as systems

__all__ = ["ROUTERS"]

ROUTERS = (sweeps, health, systems, runs)
