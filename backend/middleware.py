"""ASGI pieces around the app that are not about exposure (see :mod:`backend.guard` for those):
the request body's size limit, and HEAD answered on every GET route."""

from __future__ import annotations

from starlette.exceptions import HTTPException as StarletteHTTPException

from .errors import error_response, too_large

__all__ = ["BodySizeLimit", "HeadAsGet"]


class _BodyTooLarge(StarletteHTTPException):
    def __init__(self):
        super().__init__(status_code=413, detail="request body too large")


class BodySizeLimit:
    """Pure ASGI: refuse request bodies over ``limit`` bytes with 413 (in the one error shape).

    A declared Content-Length over the limit is refused before anything is read; a body
    without one (chunked) is counted as it is read, and reading stops past the limit.
    (FastAPI's own ``max_body_size`` answers such requests in plain text.)
    """

    def __init__(self, app, limit: int):
        self.app, self.limit = app, limit

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http":
            return await self.app(scope, receive, send)
        for name, value in scope.get("headers") or ():
            if name == b"content-length" and value.isdigit() and int(value) > self.limit:
                response = error_response(413, [too_large(int(value), self.limit)])
                return await response(scope, receive, send)
        seen = 0

        async def counted():
            nonlocal seen
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.limit:
                    raise _BodyTooLarge()  # FastAPI passes HTTPExceptions to the handlers
            return message

        return await self.app(scope, counted, send)


class HeadAsGet:
    """Pure ASGI: answer HEAD on every GET route like GET, without the body (FastAPI's routes
    answer only the methods they declare; HTTP says a GET resource also answers HEAD)."""

    def __init__(self, app):
        self.app = app

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "HEAD":
            return await self.app(scope, receive, send)

        async def headers_only(message):
            if message["type"] == "http.response.body":
                if message.get("more_body", False):
                    return
                message = {"type": "http.response.body", "body": b"", "more_body": False}
            await send(message)

        return await self.app({**scope, "method": "GET"}, receive, headers_only)
