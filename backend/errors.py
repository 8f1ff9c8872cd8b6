"""One error shape for every 4xx/5xx answer.

    {"detail": [{"loc": ["body", "params", "rho"], "field": "params.rho",
                 "value": -1.0, "reason": "out of range",
                 "allowed": "a finite number in (0, 1000] kg/m^3",
                 "msg": "params.rho: got -1.0 (out of range); allowed: ...",
                 "type": "value_error"}]}

Schema errors found by pydantic (types, NaN/Infinity, ranges, unknown fields), checks
made by nmkane (``InputError``: unknown system or model, steps over the cap, an
inconsistent initial state), oversize bodies, unknown ids, overload and a run store whose disk
or file failed (507 for a full disk, 503 otherwise) all answer this
way: ``loc`` is the path (FastAPI's convention, starting with ``body``, ``query`` or
``path``), ``field`` the same path as the CLI writes it, ``value`` what was given
(JSON-safe, long values shortened), ``reason`` what is wrong with it, ``allowed`` what
would be accepted, and ``msg`` all of it in one sentence.
"""

from __future__ import annotations

import logging
import math
import re
from collections.abc import Iterable, Iterator
from typing import Any

from fastapi import FastAPI, Request
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from pydantic import BaseModel, Field
from starlette.exceptions import HTTPException as StarletteHTTPException

from nmkane_core.errors import InconsistentStateError, InputError
from nmkane_core.schema import RunSettings, allowed, field_range

from .store import StoreError, StoreFull

__all__ = [
    "ErrorItem",
    "ErrorResponse",
    "HANDLERS",
    "error_doc",
    "error_response",
    "install_error_handlers",
    "item",
    "not_found",
    "plain",
    "too_large",
]

log = logging.getLogger("nmkane.backend")


class ErrorItem(BaseModel):
    loc: list[str | int] = Field(description='where: path of the offending input, e.g. ["body", "dt"]')
    field: str = Field(description="the same path, dotted, without the body/query/path prefix")
    msg: str = Field(description="one sentence: field, value, reason and what is allowed")
    type: str = Field(description="machine-readable error kind, e.g. greater_than, finite_number, value_error")
    value: Any = Field(None, description="the value given (JSON-safe; long values shortened)")
    reason: str | None = Field(None, description="what is wrong with the value")
    allowed: str | None = Field(None, description="what would be accepted")


class ErrorResponse(BaseModel):
    detail: list[ErrorItem]


MAX_ECHO = 200  # characters of an offending value echoed back
MAX_ECHO_DIGITS = 30  # digits of an integer echoed back whole


def text(value: str, limit: int | None = None) -> str:
    """``value`` as text that encodes as UTF-8: lone surrogates (valid in a JSON string, not in
    UTF-8) are written as ``\\udXXX`` escapes; with ``limit``, shortened to that many characters."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        value = value.encode("utf-8", "backslashreplace").decode("utf-8")
    if limit is not None and len(value) > limit:
        value = value[:limit] + f"… ({len(value)} characters)"
    return value


def plain(value: Any, depth: int = 0) -> Any:
    """A short, JSON-safe copy of an offending input value (non-finite numbers as strings, text
    made UTF-8-safe, long strings and integers shortened)."""
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        if abs(value) < 10**MAX_ECHO_DIGITS:
            return value
        digits = int(value.bit_length() * 0.30103) + 1  # str() of a huge int is slow or refused
        return f"{'-' if value < 0 else ''}an integer of about {digits:,} digits"
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value).replace("nan", "NaN").replace("inf", "Infinity")
    if isinstance(value, str):
        return text(value, MAX_ECHO)
    if isinstance(value, (bytes, bytearray)):
        return text(bytes(value[: MAX_ECHO + 1]).decode("utf-8", "replace"), MAX_ECHO)
    if depth >= 3:
        return "…"
    if isinstance(value, dict):
        items = list(value.items())
        out = {text(str(k), 100): plain(v, depth + 1) for k, v in items[:20]}
        if len(items) > 20:
            out["…"] = f"{len(items) - 20} more"
        return out
    if isinstance(value, (list, tuple)):
        seq: list = [plain(v, depth + 1) for v in value[:20]]
        if len(value) > 20:
            seq.append(f"… {len(value) - 20} more")
        return seq
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return plain(value.tolist(), depth)
    return plain(repr(value), depth)


def _field(loc: list) -> str:
    rest = loc[1:] if loc and loc[0] in ("body", "query", "path", "header") else loc
    return ".".join(str(p) for p in rest) or (str(loc[0]) if loc else "")


def _loc(loc: list) -> list:
    return [p if isinstance(p, int) else text(str(p), 100) for p in loc]


def _sentence(field: str, value: Any, reason: str | None, allowed: str | None) -> str:
    text = f"{field or 'request'}: got {value!r}" if value is not None else f"{field or 'request'}"
    if reason:
        text += f" ({reason})"
    if allowed:
        text += f"; allowed: {allowed}"
    return text


def item(
    loc: list,
    type: str,
    value: Any = None,
    reason: str | None = None,
    allowed: str | None = None,
    msg: str | None = None,
) -> dict:
    loc = _loc(loc)
    field = _field(loc)
    value = plain(value)
    reason = None if reason is None else text(reason, 2 * MAX_ECHO)
    allowed = None if allowed is None else text(allowed, 2 * MAX_ECHO)
    msg = _sentence(field, value, reason, allowed) if msg is None else _short_msg(msg)
    return {"loc": loc, "field": field, "msg": msg, "type": type, "value": value, "reason": reason, "allowed": allowed}


def _short_msg(msg: str) -> str:
    """A message made elsewhere (``InputError``): UTF-8-safe, with long runs of characters (an
    echoed value) shortened."""
    msg = text(msg)
    return re.sub(rf"\S{{{MAX_ECHO + 1},}}", lambda m: m.group()[:MAX_ECHO] + "…", msg)


def too_large(size: int | None, limit: int) -> dict:
    """The item of a request body over ``limit`` bytes (``size``: its declared length, if known)."""
    return item(["body"], "too_large", size, "request body too large", f"at most {limit:,} bytes")


def error_doc(description: str, **more: Any) -> dict[str, Any]:
    """An error answer as the OpenAPI document lists it (``responses=``): the one shape."""
    return {"model": ErrorResponse, "description": description, **more}


def not_found(param: str, value: str, what: str, source: str) -> JSONResponse:
    """404 for an id that names nothing: ``param`` the path parameter, ``what`` the kind of
    thing (``run``), ``source`` where ids come from (``POST /api/runs``)."""
    return error_response(
        404, [item(["path", param], "not_found", value, f"no {what} with this id", f"an id returned by {source}")]
    )


def error_response(status: int, items: list[dict], headers: dict | None = None) -> JSONResponse:
    return JSONResponse(status_code=status, content={"detail": items}, headers=headers)


_TYPE_ALLOWED = {
    "float_type": "a number",
    "float_parsing": "a number",
    "int_type": "an integer",
    "int_parsing": "an integer",
    "int_from_float": "an integer",
    "bool_type": "true or false",
    "bool_parsing": "true or false",
    "string_type": "a string",
    "dict_type": "a JSON object",
    "list_type": "a JSON array",
    "model_attributes_type": "a JSON object with the run settings",
    "finite_number": "a finite number (NaN and Infinity are not JSON numbers)",
    "json_invalid": "a JSON object with the run settings",
    "missing": "a value (required)",
}
_BOUNDS = {"gt": ">", "ge": "≥", "lt": "<", "le": "≤"}


def _allowed(err: dict) -> str | None:
    ctx = err.get("ctx") or {}
    kind = err.get("type", "")
    loc = list(err.get("loc") or ())
    if loc[:1] == ["body"] and len(loc) == 2 and loc[1] in RunSettings.model_fields and field_range(loc[1]):
        return allowed(loc[1])  # a run setting's range, in the words every face uses
    bounds = [f"{_BOUNDS[k]} {ctx[k]}" for k in ("gt", "ge", "lt", "le") if k in ctx]
    if bounds:
        return "a number " + " and ".join(bounds)
    if kind == "literal_error" and "expected" in ctx:
        return str(ctx["expected"])
    if kind == "extra_forbidden":
        return "the documented fields: " + ", ".join(RunSettings.model_fields)
    if kind == "string_too_long" and "max_length" in ctx:
        return f"a string of at most {ctx['max_length']} characters"
    if kind == "string_too_short" and "min_length" in ctx:
        return f"a string of at least {ctx['min_length']} character{'s' if ctx['min_length'] != 1 else ''}"
    return _TYPE_ALLOWED.get(kind)


def validation_items(exc: RequestValidationError) -> list[dict]:
    items = []
    for err in exc.errors():
        loc = list(err.get("loc", ()))
        kind = err.get("type", "value_error")
        reason = err.get("msg", "")
        if kind == "json_invalid":  # FastAPI puts the character position in loc
            where = f" at character {loc[1]}" if len(loc) > 1 and isinstance(loc[1], int) else ""
            reason = f"not valid JSON{where}: {(err.get('ctx') or {}).get('error', 'decode error')}"
            loc, value = ["body"], None
        else:
            value = err.get("input")
            reason = reason.replace("Input should be", "should be")
        items.append(item(loc, kind, value, reason, _allowed(err)))
    return items


def input_error_item(exc: InputError) -> dict:
    loc = ["body", *[int(p) if p.isdigit() else p for p in str(exc.field).split(".")]]
    kind = "inconsistent_state" if isinstance(exc, InconsistentStateError) else "value_error"
    return item(loc, kind, exc.value, exc.reason, exc.allowed, msg=str(exc))


# -- the handlers: one per kind of error ------------------------------------------------
async def on_validation_error(request: Request, exc: RequestValidationError) -> JSONResponse:
    """Schema errors: 422 with one item each; a body not declared as JSON: 415."""
    if any(isinstance(e.get("input"), (bytes, bytearray)) for e in exc.errors()):
        # FastAPI hands over the raw bytes when the content type is not JSON
        return error_response(415, [_not_json(request.headers.get("content-type", ""))])
    return error_response(422, validation_items(exc))


def _not_json(content_type: str) -> dict:
    return item(
        ["header", "content-type"],
        "unsupported_media_type",
        content_type,
        "the body is not declared as JSON",
        "Content-Type: application/json (a JSON object with the run settings)",
    )


async def on_input_error(request: Request, exc: InputError) -> JSONResponse:
    """nmkane's own checks: 422, one item per field (an error may name several)."""
    parts = getattr(exc, "errors", None) or [exc]
    return error_response(422, [input_error_item(e) for e in parts])


async def on_store_full(request: Request, exc: StoreFull) -> JSONResponse:
    """The store at its cap (policy ``refuse``): 507, saying how to make room."""
    return error_response(
        507,
        [
            item(
                ["store"],
                "store_full",
                None,
                "the run store is full",
                "delete runs (DELETE /api/runs/{id}, `nmkane store prune`) or raise "
                "NMKANE_MAX_STORED_RUNS / NMKANE_MAX_STORE_MB, or set "
                "NMKANE_STORE_FULL=evict-oldest",
                msg=str(exc),
            )
        ],
    )


async def on_store_error(request: Request, exc: StoreError) -> JSONResponse:
    """The run store's disk or file failed (:class:`~backend.store.StoreError`): 507 for a full
    disk, 503 otherwise; the message names the file and what to do.  Logged in one line too:
    whoever runs the service has to act."""
    log.warning("%s %s: %s", request.method, request.url.path, exc)
    return error_response(exc.status, [item(["store"], exc.kind, None, exc.reason, exc.remedy, msg=str(exc))])


async def on_http_error(request: Request, exc: StarletteHTTPException) -> JSONResponse:
    """HTTP errors raised by FastAPI and starlette (413, 400, 404, 405, others) in the one shape."""
    headers = dict(exc.headers or {})
    status = exc.status_code
    if status == 413:
        it = too_large(None, request.app.state.settings.max_request_bytes)
    elif status == 400:  # FastAPI could not read the body (e.g. not UTF-8)
        cause = exc.__cause__ or exc.__context__
        reason = f"{exc.detail}: {type(cause).__name__}: {cause}" if cause else str(exc.detail)
        it = item(["body"], "invalid_body", None, reason, "a JSON object in UTF-8 with the run settings")
    elif status == 404:
        it = item(["path"], "not_found", request.url.path, "no such resource", "the routes listed at /docs")
    elif status == 405:
        methods = allowed_methods(request.app.routes, request.url.path)
        headers["Allow"] = ", ".join(methods)
        it = item(
            ["method"], "method_not_allowed", request.method, "method not allowed on this path", ", ".join(methods)
        )
    else:
        it = item([], f"http_{status}", None, str(exc.detail), None, msg=str(exc.detail))
    return error_response(status, [it], headers=headers)


async def on_unexpected(request: Request, exc: Exception) -> JSONResponse:
    """Anything else: logged with its traceback; the client gets 500 without details, and
    ``Connection: close``: starlette raises the exception again to the server after this
    answer, and uvicorn then closes the connection; said so, a client sends its next request
    on a new one instead of losing it to a reset keep-alive connection."""
    log.exception("unexpected error on %s %s", request.method, request.url.path)
    return error_response(
        500,
        [
            item(
                [],
                "internal_error",
                None,
                type(exc).__name__,
                msg="internal error: the failure was logged on the server",
            )
        ],
        headers={"Connection": "close"},
    )


def _every_route(routes: Iterable[Any]) -> Iterator[Any]:
    """The routes of an app, with those of included routers (FastAPI before 0.16x copies them
    into ``app.routes``; later versions keep an included router as one entry, its routes in
    ``original_router``)."""
    for route in routes:
        inner = getattr(route, "original_router", None)
        if inner is not None:
            yield from _every_route(inner.routes)
        else:
            yield route


def allowed_methods(routes: Iterable[Any], path: str) -> list[str]:
    """The methods of the first route whose path matches ``path`` — the route documented for it
    (``/api/runs/x.csv`` also matches ``/api/runs/{run_id}``, declared after it) — with those of
    every route declared for the same path."""
    flat = list(_every_route(routes))
    first = next((r for r in flat if getattr(r, "path_regex", None) is not None and r.path_regex.match(path)), None)
    if first is None:
        return []
    return sorted(
        {m for r in flat if getattr(r, "path", None) == first.path for m in (getattr(r, "methods", None) or ())}
    )


#: Every error rendered in the one shape above, by the exception that carries it.
HANDLERS: dict[type[Exception], Any] = {
    RequestValidationError: on_validation_error,
    InputError: on_input_error,
    StoreFull: on_store_full,
    StoreError: on_store_error,
    StarletteHTTPException: on_http_error,
    Exception: on_unexpected,
}


def install_error_handlers(app: FastAPI) -> None:
    """Render every error in the one shape above."""
    for kind, handler in HANDLERS.items():
        app.add_exception_handler(kind, handler)
