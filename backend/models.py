"""Response models of the service's own endpoints (runs use the core's ``RunResult``)."""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from nmkane_core.schema import RunSettings as CoreRunSettings
from nmkane_core.schema import RunStatus, RunSummary

__all__ = ["RunSettings", "Health", "RunListItem", "RunList", "Catalog", "STATUSES"]


class RunSettings(CoreRunSettings):
    """The run settings as a REST body: the core's schema, validated strictly, so JSON that
    violates the documented schema is refused (no booleans or numeric strings for numbers,
    no 2.0 for an integer) instead of being coerced."""

    model_config = ConfigDict(strict=True)


STATUSES = RunStatus


class Health(BaseModel):
    status: Literal["ok"]
    version: str
    runs_stored: int = Field(description="runs in the database")
    runs_in_flight: int = Field(description="runs admitted: running plus waiting for a worker")
    runs_running: int = Field(description="runs being simulated now")
    queue_limit: int = Field(description="runs admitted at once before POST /api/runs answers 503")
    sweeps_running: int = Field(0, description="sweeps running now (one at a time)")
    sweeps_queued: int = Field(0, description="sweeps admitted and waiting for the running one")
    sweep_runs_pending: int = Field(0, description="runs of the admitted sweeps not done yet")
    sweep_runs_running: int = Field(0, description="sweep runs on the run workers now")
    max_sweeps: int = Field(0, description="sweeps admitted at once before POST /api/sweeps answers 503")
    sweep_workers: int = Field(0, description="run workers a sweep may use at once")


class RunListItem(BaseModel):
    id: str
    created: str = Field(description="when the run was stored (ISO 8601, UTC)")
    system: str
    status: STATUSES
    settings: dict = Field(description="the fully resolved settings")
    summary: RunSummary


class RunList(BaseModel):
    runs: list[RunListItem] = Field(description="newest first")
    total: int = Field(description="runs matching the filters")
    limit: int
    offset: int


class Catalog(BaseModel):
    """What can be run, with which parameters, and the limits (library's and service's)."""

    model_config = ConfigDict(extra="allow")

    systems: list[dict] = Field(
        description="name, parameters with defaults and ranges, models or "
        "formulations, coordinates and speeds, constraint names, the forces at points each model declares "
        "(forces: model → name, components, route, what it acts on), defaults, what to try, the stability "
        "sweep a system declares (or null)"
    )
    integrators: dict[str, str] = Field(description="name: description")
    projections: list[str]
    limits: dict[str, int | float] = Field(description="the library's limits (counts are integers)")
    service_limits: dict[str, int | float] = Field(
        description="this service's limits (see service_limit_descriptions; counts are integers)"
    )
    service_limit_descriptions: dict[str, str]
