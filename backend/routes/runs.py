"""``/api/runs``: run a simulation and store it, list the stored runs, fetch one (JSON or
CSV), delete one.

Route functions are thin: the work is in :class:`backend.service.RunService` (worker pool,
admission, limits, encoding) and :class:`backend.store.RunStore` (SQLite).  Run documents
are encoded once, when the run finishes, and served as stored bytes; the OpenAPI document
still describes them as the core's ``RunResult``.

A stored document is streamed: read from the store's file a piece at a time and decompressed
as it is sent (:func:`document_chunks`), so a client that reads slowly, or not at all, holds
one piece and the decompressor's window (about 1 MB), not the document (a 100,000-row run is
20 MB); the read deadline of :func:`backend.guard.read_deadline_protocol` drops a client
that stops reading.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import functools
import threading
from collections.abc import AsyncIterator, Generator, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Any

import numpy as np
import orjson
from fastapi import APIRouter, Path, Query
from fastapi.responses import JSONResponse, Response, StreamingResponse

from nmkane_core.heap import malloc_trim
from nmkane_core.run.result import Run
from nmkane_core.schema import RunResult

from ..deps import AppSettings, Service, Store
from ..errors import error_doc, error_response, item, not_found
from ..models import STATUSES, RunList, RunSettings
from ..store import RunStore

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
    507: error_doc(
        "the run store is full (max_stored_runs or max_store_bytes: delete runs or raise the cap), or its "
        "disk is (disk_full: free disk space there or delete runs)"
    ),
    503: error_doc(
        "queue_limit runs already admitted (retry after Retry-After seconds); or the run store cannot be "
        "written (store_read_only) or read (store_corrupt)",
        headers={"Retry-After": {"schema": {"type": "integer"}, "description": "seconds (overloaded only)"}},
    ),
}
_STORE_FAULT = "the run store cannot be read or written (store_read_only, store_corrupt)"
NOT_FOUND: dict[int | str, dict[str, Any]] = {
    404: error_doc("no run with this id"),
    422: error_doc("malformed id"),
    503: error_doc(_STORE_FAULT),
}
_ERROR_JSON = {"content": {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorResponse"}}}}
NOT_FOUND_CSV: dict[int | str, dict[str, Any]] = {
    404: {**_ERROR_JSON, "description": "no run with this id"},
    422: {**_ERROR_JSON, "description": "malformed id"},
    503: {**_ERROR_JSON, "description": _STORE_FAULT},
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


class ClosingStream(StreamingResponse):
    """A streamed answer that closes its chunks' generator when the answer ends, sent or not.

    Starlette stops reading the generator when the client is gone (dropped at the read deadline)
    and leaves it to the garbage collector; held in a reference cycle, it stayed open until a
    cyclic collection, with what it held (a CSV's columns) and the ``_streaming`` count, so the
    heap trim after the last download waited as long."""

    async def __call__(self, scope, receive, send) -> None:
        try:
            await super().__call__(scope, receive, send)
        finally:
            aclose = getattr(self.body_iterator, "aclose", None)  # ours are async generators
            if aclose is not None:
                await aclose()


@functools.cache
def _csv_makers() -> ThreadPoolExecutor:
    """The threads that make CSV chunks: two, however many clients download (each chunk is made
    from the run's columns; starlette's pool has 40 threads, each with its malloc arena, and an
    idle one kept the arguments of its last call: a dropped client's generator)."""
    return ThreadPoolExecutor(2, thread_name_prefix="nmkane-csv")


async def made_in_thread(chunks: Generator[str, None, None]) -> AsyncIterator[str]:
    """The chunks of ``chunks``, each made in a CSV thread; ``chunks`` is closed when this ends
    (after the chunk under way, when the client left while it was made)."""
    making: Future[str | None] | None = None
    try:
        while True:
            making = _csv_makers().submit(next, chunks, None)
            chunk = await asyncio.wrap_future(making)
            if chunk is None:
                return
            yield chunk
    finally:
        if making is not None and not making.done():
            making.add_done_callback(lambda _: chunks.close())
        else:
            chunks.close()


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
    return ClosingStream(
        made_in_thread(csv_chunks(doc)),
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
async def get_run(store: Store, run_id: str = RUN_ID):
    """The stored run result document, exactly as POST /api/runs answered it."""
    found = await document_chunks(store, run_id)
    if found is None:
        return _no_run(run_id)
    size, chunks = found
    headers = {"Content-Length": str(size)} if size >= 0 else None
    return ClosingStream(chunks, media_type=JSONBytes.media_type, headers=headers)


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
    chunks = _csv_chunks(doc, rows_per_chunk)
    del doc  # only the chunks' generator holds it, until it has read the columns
    with _streaming():
        try:
            yield from chunks
        finally:
            chunks.close()  # its columns freed before the heap is trimmed
            del chunks


def _csv_chunks(doc: bytes, rows_per_chunk: int):
    d = orjson.loads(doc)
    del doc  # a slow client holds the columns below while they stream, not the document too
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


PIECE_BYTES = 32 * 1024  # of the stored (compressed) document, read at a time: ~75 kB of JSON


async def document_chunks(
    store: RunStore, run_id: str, piece: int = PIECE_BYTES
) -> tuple[int, AsyncIterator[bytes]] | None:
    """The stored document of ``run_id`` as its length in bytes (-1 when the stored frame does
    not say) and its bytes in chunks, decompressed a piece at a time; None when there is no such
    run.  The first piece is read now (a missing run is known, a store fault raised, before an
    answer starts).

    Each piece is read in a transaction of its own (the row found by id, then an incremental
    read of its blob), so a slow download keeps no read transaction open; a run deleted while
    it downloads ends the download with an error (the client sees it cut short).  The next piece
    is read when the connection has taken the previous one (uvicorn's ``send`` waits while the
    connection's buffer is past its high-water mark).
    """
    first = await _read(store, run_id, 0, piece)
    if first is None:
        return None
    size, decoder = store.piece_decoder(first)
    return size, _decoded(store, run_id, first, piece, decoder)


async def _decoded(store: RunStore, run_id: str, blob: bytes, piece: int, decoder: Any) -> AsyncIterator[bytes]:
    with _streaming():
        try:
            offset = 0
            while blob:
                yield decoder.decompress(blob)  # 32 kB: ~50 µs, on the event loop
                offset += len(blob)
                more = await _read(store, run_id, offset, piece)
                if more is None:
                    raise LookupError(f"run {run_id} was deleted while it was being sent")
                blob = more
            yield decoder.flush()
        finally:
            del decoder, blob  # freed before the heap is trimmed


@functools.cache
def _reads() -> ThreadPoolExecutor:
    """The threads that read documents' pieces: two, however many clients download (each thread
    keeps its own SQLite connection and page cache, and its own malloc arena)."""
    return ThreadPoolExecutor(2, thread_name_prefix="nmkane-document")


def _read(store: RunStore, run_id: str, offset: int, size: int) -> asyncio.Future[bytes | None]:
    return asyncio.get_running_loop().run_in_executor(_reads(), store.document_piece, run_id, offset, size)


_streams = [0]  # documents (JSON or CSV) being sent
_streams_lock = threading.Lock()


@contextlib.contextmanager
def _streaming() -> Iterator[None]:
    """Count a document being sent; when the last one ends (sent, or its client gone), give the
    heap it freed back to the system.  Without it glibc keeps the freed pieces, decompressors and
    buffers in its arenas: measured, 40 clients that read nothing left the process 50 MB larger
    after they had gone, and ``malloc_trim(0)`` (a millisecond) returned all of it."""
    with _streams_lock:
        _streams[0] += 1
    try:
        yield
    finally:
        with _streams_lock:
            _streams[0] -= 1
            last = _streams[0] == 0
        if last and malloc_trim is not None:
            _reads().submit(malloc_trim, 0)
