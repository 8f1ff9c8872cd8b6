"""``/api/runs``: run a simulation and store it, list the stored runs, fetch one (JSON or
CSV), delete one.

Route functions are thin: the work is in :class:`backend.service.RunService` (worker pool,
admission, limits, encoding) and :class:`backend.store.RunStore` (SQLite).  Run documents
are encoded once, when the run finishes, and served as stored bytes; the OpenAPI document
still describes them as the core's ``RunResult``.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

import numpy as np
import orjson
from fastapi import APIRouter, Path, Query
from fastapi.responses import JSONResponse, Response, StreamingResponse

from nmkane_core.run.result import Run
from nmkane_core.schema import RunResult

from ..deps import AppSettings, Service, Store
from ..errors import error_doc, error_response, item, not_found
from ..models import STATUSES, RunList, RunSettings

__all__ = ["router", "CSVResponse", "JSONBytes"]

router = APIRouter()

RUN_ID = Path(description="the run's id, as returned by POST /api/runs", min_length=1, max_length=64)

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
    400: error_doc("the body could not be read as text (e.g. not UTF-8)"),
    413: error_doc("request body larger than max_request_bytes"),
    415: error_doc("the body is not declared as JSON (Content-Type)"),
    422: error_doc("invalid settings: field path, value, reason and what is allowed"),
    507: error_doc("the run store is full (max_stored_runs or max_store_bytes); delete runs or raise the cap"),
    503: error_doc(
        "queue_limit runs already admitted; retry after Retry-After seconds",
        headers={"Retry-After": {"schema": {"type": "integer"}, "description": "seconds"}},
    ),
}
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: error_doc("no run with this id"),
    422: error_doc("malformed id"),
}
_ERROR_JSON = {"content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorResponse"}}}}
NOT_FOUND_CSV: dict[int | str, dict[str, Any]] = {
    404: {**_ERROR_JSON, "description": "no run with this id"},
    422: {**_ERROR_JSON, "description": "malformed id"},
}
DELETE_RESPONSES: dict[int | str, dict[str, Any]] = {
    **NOT_FOUND,
    401: error_doc("an access token is asked for and was missing or wrong"),
}


class JSONBytes(JSONResponse):
    """JSON already encoded (orjson); documented by the route's ``response_model``."""

    def render(self, content) -> bytes:
        return content


class CSVResponse(Response):
    media_type = "text/csv"


@router.post(
    "/api/runs",
    status_code=201,
    response_model=RunResult,
    response_class=JSONBytes,
    responses=POST_RESPONSES,
    operation_id="create_run",
)
async def create_run(body: RunSettings, svc: Service, settings: AppSettings):
    """Run a simulation and store it; answers 201 with the run result document and its
    `Location`. Omitted fields take the system's defaults."""
    if not svc.admit():
        return _overloaded(settings.queue_limit, svc.retry_after())
    try:
        run_id, doc = await svc.run(body)
    finally:
        svc.release()
    return JSONBytes(doc, status_code=201, headers={"Location": f"/api/runs/{run_id}"})


def _overloaded(queue_limit: int, wait: int) -> JSONResponse:
    return error_response(
        503,
        [item([], "overloaded", None, f"{queue_limit} runs already admitted", f"retry after {wait} s")],
        headers={"Retry-After": str(wait)},
    )


@router.get("/api/runs", response_model=RunList, response_class=JSONBytes, operation_id="list_runs")
def list_runs(
    store: Store,
    limit: int = Query(20, ge=1, le=200, description="runs per page"),
    offset: int = Query(0, ge=0, le=2**62, description="runs to skip (newest first)"),
    system: str | None = Query(None, max_length=64, description="only runs of this system"),
    status: STATUSES | None = Query(None, description="only runs with this status"),
):
    """Recent runs, newest first: id, time, system, status, resolved settings and summary."""
    runs = store.list(limit, offset, system, status)
    for r in runs:
        r["created"] = _iso(r["created"])
    total = store.count(system, status)
    return JSONBytes(orjson.dumps({"runs": runs, "total": total, "limit": limit, "offset": offset}))


@router.get("/api/runs/{run_id}.csv", response_class=CSVResponse, responses=NOT_FOUND_CSV, operation_id="get_run_csv")
def get_run_csv(store: Store, run_id: str = RUN_ID):
    """The stored run as CSV: t, the state, energy, violation_<constraint>, force_<speed>,
    multiplier_<constraint> and the declared forces at points, <force>.<component> (one row per
    output step)."""
    doc = store.document(run_id)
    if doc is None:
        return _no_run(run_id)
    return StreamingResponse(
        csv_chunks(doc),
        media_type=CSVResponse.media_type,
        headers={"Content-Disposition": f'attachment; filename="{run_id}.csv"'},
    )


@router.get(
    "/api/runs/{run_id}",
    response_model=RunResult,
    response_class=JSONBytes,
    responses=NOT_FOUND,
    operation_id="get_run",
)
def get_run(store: Store, run_id: str = RUN_ID):
    """The stored run result document, exactly as POST /api/runs answered it."""
    doc = store.document(run_id)
    if doc is None:
        return _no_run(run_id)
    return JSONBytes(doc)


@router.delete("/api/runs/{run_id}", status_code=204, responses=DELETE_RESPONSES, operation_id="delete_run")
def delete_run(store: Store, run_id: str = RUN_ID):
    """Delete a stored run (its document, CSV and listing entry)."""
    if not store.delete(run_id):
        return _no_run(run_id)
    return Response(status_code=204)


def _no_run(run_id: str) -> JSONResponse:
    return not_found("run_id", run_id, "run", "POST /api/runs")


def _iso(ts: float) -> str:
    return dt.datetime.fromtimestamp(ts, dt.UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def csv_chunks(doc: bytes, rows_per_chunk: int = 5000):
    """The CLI's CSV (``Run.to_csv``) of a stored document, in chunks of rows.

    Each chunk is ``Run.to_csv`` of a slice (header kept on the first only), so the text is
    exactly the CLI's, and a long run streams without holding the GIL for seconds.
    """
    d = orjson.loads(doc)
    t = _floats(d["t"])
    state = {k: _floats(v) for k, v in d["state"].items()}
    energy = None if d["energy"] is None else _floats(d["energy"])
    violation = {k: _floats(v) for k, v in d["violation"].items()}
    forces = {k: _floats(v) for k, v in d.get("constraint_forces", {}).items()}
    multipliers = {k: _floats(v) for k, v in d.get("multipliers", {}).items()}
    at_points = {k: _floats(v) for k, v in d.get("point_forces", {}).items()}
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
            constraint_forces={k: v[part] for k, v in forces.items()},
            multipliers={k: v[part] for k, v in multipliers.items()},
            point_forces={k: v[part] for k, v in at_points.items()},
        ).to_csv()
        yield text if start == 0 else text.split("\n", 1)[1]


def _floats(values) -> np.ndarray:
    return np.asarray(values, dtype=float)
