"""What stands between the network and the REST API: Host allow-list, token, read deadline.

The rule for hosts and tokens is the one the web app's server keeps too,
:mod:`nmkane_core.access`; here it is applied to ASGI requests.

* :class:`HostCheck` (ASGI): a request whose ``Host`` is neither one of the allowed names nor
  an IP address gets 400 (DNS rebinding: a page on ``evil.example`` that resolves to
  127.0.0.1 sends ``Host: evil.example``).  Loopback names are always allowed; ``nmkane
  serve`` adds the bound address and ``--allow-host`` names.  (starlette's
  ``TrustedHostMiddleware`` does not fit: it has no rule for IP addresses and answers in
  plain text, not in the service's error shape.)
* :class:`TokenCheck` (ASGI): with a token configured, every request that writes (not GET,
  HEAD or OPTIONS), and every read of the stored runs and sweeps, must carry
  ``Authorization: Bearer <token>``; otherwise 401 with a
  ``WWW-Authenticate`` header.  The header is read as FastAPI's ``HTTPBearer`` reads it
  (``get_authorization_scheme_param``; the scheme in any case); ``HTTPBearer`` itself, a
  dependency of each route, would not guard paths without a route, and would change the
  OpenAPI document whether a token is configured or not.  ``nmkane serve`` makes a token
  (:func:`nmkane_core.access.new_token`) when it binds a non-loopback address.
* :func:`read_deadline_protocol`: uvicorn's HTTP protocol with a deadline on reading a
  request — its head and its body — so a client that stops sending is answered 408 and
  disconnected instead of holding a connection for ever (uvicorn's own ``timeout_keep_alive``
  only covers the idle time between requests); and the symmetric deadline on the client's
  reading of the answer: a connection whose unsent answer has waited that long for the client
  to take any of it is dropped (asyncio's transport pauses the answer past its 64 KiB
  high-water mark; a client that reads nothing never resumes it).
"""

from __future__ import annotations

import asyncio

from fastapi.security.utils import get_authorization_scheme_param

from nmkane_core.access import HostAllowList, token_matches

from .errors import error_response, item

__all__ = ["HostCheck", "TokenCheck", "read_deadline_protocol"]


def _header(scope, name: bytes) -> str | None:
    """A request header's value (the first, as text), or None."""
    raw = next((v for k, v in scope.get("headers") or () if k == name), None)
    return None if raw is None else raw.decode("latin-1")


class HostCheck:
    """Pure ASGI: refuse (400) requests whose ``Host`` the allow-list ``rule`` does not admit
    (neither one of its names nor an IP address)."""

    def __init__(self, app, rule: HostAllowList):
        self.app = app
        self.rule = rule

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        host = _header(scope, b"host") or ""
        if self.rule.admits(host):
            return await self.app(scope, receive, send)
        return await self.refusal(host)(scope, receive, send)

    def refusal(self, host: str):
        allowed = "Host: " + ", ".join(sorted(self.rule.names))
        return error_response(
            400,
            [
                item(
                    ["header", "host"],
                    "host_not_allowed",
                    host,
                    "this server does not answer to that host name (a protection against DNS rebinding)",
                    allowed + " (add names with `nmkane serve --allow-host NAME` or NMKANE_ALLOWED_HOSTS)",
                )
            ],
        )


class TokenCheck:
    """Pure ASGI: with ``token``, requests that write, and every request for the stored runs and
    sweeps (users' data: reading them is not for anyone who can reach the port), need
    ``Authorization: Bearer <token>`` (401).  The health route, the catalogue of systems and the
    API's documentation stay open to reads (they hold no user's data); CORS preflights too."""

    READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})
    #: paths under which reads need the token as well
    PRIVATE_PREFIXES = ("/api/runs", "/api/sweeps")

    def __init__(self, app, token: str):
        self.app = app
        self.token = token

    async def __call__(self, scope, receive, send):
        private = scope.get("path", "").startswith(self.PRIVATE_PREFIXES) and scope.get("method") != "OPTIONS"
        if scope["type"] != "http" or (scope["method"] in self.READ_METHODS and not private):
            return await self.app(scope, receive, send)
        header = _header(scope, b"authorization")
        scheme, given = get_authorization_scheme_param(header)
        if scheme.lower() == "bearer" and token_matches(given, self.token):
            return await self.app(scope, receive, send)
        return await self.refusal(sent=bool(header))(scope, receive, send)

    @staticmethod
    def refusal(sent: bool):
        return error_response(
            401,
            [
                item(
                    ["header", "authorization"],
                    "unauthorized",
                    None,
                    "missing or wrong access token" if sent else "this service asks for an access token for runs",
                    "Authorization: Bearer <the token printed by `nmkane serve` at start>",
                )
            ],
            headers={"WWW-Authenticate": 'Bearer realm="nmkane"'},
        )


_TIMEOUT_BODY = (
    b'{"detail":[{"loc":["body"],"field":"body","msg":"request timeout: the request was not sent '
    b'in time","type":"request_timeout","value":null,"reason":"the request (head and body) was not '
    b'received within the read timeout","allowed":null}]}'
)


def read_deadline_protocol(seconds: float, write_seconds: float | None = None):
    """uvicorn's httptools protocol with a deadline of ``seconds`` on reading each request, and
    one of ``write_seconds`` (the same by default) on the client's reading of each answer.

    The read clock starts when a connection opens (and again when a keep-alive connection
    starts its next request) and stops when the request's body is complete; at the deadline the
    client gets 408 (if nothing was answered yet) and the connection is closed.  The write clock
    starts when the transport pauses the answer (more than its high-water mark waits unsent)
    and stops when the client has taken enough of it to resume; at the deadline the connection
    is dropped with what waited unsent, so a client that stops reading holds neither a
    connection nor the answer's bytes for longer than that."""
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

    class ReadDeadlineProtocol(HttpToolsProtocol):
        read_timeout = seconds
        write_timeout = seconds if write_seconds is None else write_seconds
        _deadline: asyncio.TimerHandle | None = None
        _write_deadline: asyncio.TimerHandle | None = None

        def connection_made(self, transport):
            super().connection_made(transport)
            self._deadline = self.loop.call_later(self.read_timeout, self._too_slow)

        def on_message_begin(self) -> None:
            super().on_message_begin()
            if getattr(self, "_deadline", None) is None:
                self._deadline = self.loop.call_later(self.read_timeout, self._too_slow)

        def on_message_complete(self) -> None:
            self._cancel_deadline()
            super().on_message_complete()

        def connection_lost(self, exc):
            self._cancel_deadline()
            self._cancel_write_deadline()
            super().connection_lost(exc)

        def pause_writing(self) -> None:
            super().pause_writing()
            if self._write_deadline is None:
                self._write_deadline = self.loop.call_later(self.write_timeout, self._not_reading)

        def resume_writing(self) -> None:
            self._cancel_write_deadline()
            super().resume_writing()

        def _cancel_write_deadline(self) -> None:
            if self._write_deadline is not None:
                self._write_deadline.cancel()
                self._write_deadline = None

        def _not_reading(self) -> None:
            self._write_deadline = None
            self.transport.abort()  # close() would wait for the client to take the unsent bytes

        def _cancel_deadline(self) -> None:
            deadline = getattr(self, "_deadline", None)
            if deadline is not None:
                deadline.cancel()
                self._deadline = None

        def _too_slow(self) -> None:
            self._deadline = None
            if self.transport.is_closing():
                return
            cycle = self.cycle
            if cycle is None or not cycle.response_started:
                self.transport.write(
                    b"HTTP/1.1 408 Request Timeout\r\ncontent-type: application/json\r\n"
                    b"connection: close\r\ncontent-length: "
                    + str(len(_TIMEOUT_BODY)).encode()
                    + b"\r\n\r\n"
                    + _TIMEOUT_BODY
                )
            if cycle is not None:
                cycle.disconnected = True
                cycle.message_event.set()
            self.transport.close()

    return ReadDeadlineProtocol
