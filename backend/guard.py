"""What stands between the network and the REST API: Host allow-list, token, read deadline.

* :class:`HostCheck` (ASGI): a request whose ``Host`` is neither one of the allowed names nor
  an IP address gets 400 (DNS rebinding: a page on ``evil.example`` that resolves to
  127.0.0.1 sends ``Host: evil.example``).  Loopback names are always allowed; ``nmkane
  serve`` adds the bound address and ``--allow-host`` names.
* :class:`TokenCheck` (ASGI): with a token configured, every request that writes (not GET,
  HEAD or OPTIONS) must carry ``Authorization: Bearer <token>``; otherwise 401.
  ``nmkane serve`` makes one (``secrets``) when it binds a non-loopback address.
* :func:`read_deadline_protocol`: uvicorn's HTTP protocol with a deadline on reading a
  request — its head and its body — so a client that stops sending is answered 408 and
  disconnected instead of holding a connection for ever (uvicorn's own ``timeout_keep_alive``
  only covers the idle time between requests).
"""

from __future__ import annotations

import asyncio
import ipaddress
import secrets
from collections.abc import Iterable

from .errors import error_response, item

__all__ = [
    "LOOPBACK_NAMES",
    "HostCheck",
    "TokenCheck",
    "allowed_host_names",
    "host_allowed",
    "host_name",
    "is_loopback",
    "new_token",
    "read_deadline_protocol",
]

LOOPBACK_NAMES = ("localhost", "127.0.0.1", "::1")


def new_token() -> str:
    """A fresh access token: 192 random bits, URL-safe."""
    return secrets.token_urlsafe(24)


def is_loopback(host: str) -> bool:
    """True for a loopback address or ``localhost`` (what ``--host`` may bind without a token)."""
    host = host.strip("[]").lower()
    if host == "localhost" or host.endswith(".localhost"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def host_name(value: str) -> str:
    """The name in a ``Host`` header, without the port (``[::1]:8000`` → ``::1``), lower case."""
    value = value.strip().lower()
    if value.startswith("["):
        return value[1 : value.find("]")] if "]" in value else value
    if value.count(":") == 1:
        return value.split(":", 1)[0]
    return value


def allowed_host_names(bound: str | None = None, extra: Iterable[str] = ()) -> tuple[str, ...]:
    """Loopback names, the bound address (unless a wildcard) and ``extra`` names."""
    names = list(LOOPBACK_NAMES)
    if bound and bound not in ("0.0.0.0", "::", ""):
        names.append(host_name(bound) if bound.startswith("[") else bound.lower())
    names += [host_name(n) if ":" in n and not n.count(":") > 1 else n.strip("[]").lower() for n in extra]
    return tuple(dict.fromkeys(names))


def _is_ip(name: str) -> bool:
    try:
        ipaddress.ip_address(name)
        return True
    except ValueError:
        return False


def host_allowed(name: str, allowed: Iterable[str]) -> bool:
    """``name`` (from :func:`host_name`) is an allowed name or an IP address: a browser that
    addresses a server by IP involves no DNS, so no rebinding."""
    return name in allowed or _is_ip(name)


class HostCheck:
    """Pure ASGI: refuse (400) requests whose ``Host`` is neither in ``allowed`` (names without
    port) nor an IP address."""

    def __init__(self, app, allowed: Iterable[str]):
        self.app = app
        self.allowed = frozenset(n.lower() for n in allowed)

    async def __call__(self, scope, receive, send):
        if scope["type"] not in ("http", "websocket"):
            return await self.app(scope, receive, send)
        raw = next((v for k, v in scope.get("headers") or () if k == b"host"), b"")
        name = host_name(raw.decode("latin-1"))
        if host_allowed(name, self.allowed):
            return await self.app(scope, receive, send)
        response = error_response(
            400,
            [
                item(
                    ["header", "host"],
                    "host_not_allowed",
                    raw.decode("latin-1"),
                    "this server does not answer to that host name (a protection against DNS rebinding)",
                    "Host: " + ", ".join(sorted(self.allowed)) + " (add names with `nmkane serve --allow-host NAME` "
                    "or NMKANE_ALLOWED_HOSTS)",
                )
            ],
        )
        return await response(scope, receive, send)


class TokenCheck:
    """Pure ASGI: with ``token``, requests that write need ``Authorization: Bearer <token>`` (401)."""

    READ_METHODS = frozenset({"GET", "HEAD", "OPTIONS"})

    def __init__(self, app, token: str):
        self.app = app
        self.expected = f"Bearer {token}".encode()

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] in self.READ_METHODS:
            return await self.app(scope, receive, send)
        given = next((v for k, v in scope.get("headers") or () if k == b"authorization"), b"")
        if secrets.compare_digest(given, self.expected):
            return await self.app(scope, receive, send)
        response = error_response(
            401,
            [
                item(
                    ["header", "authorization"],
                    "unauthorized",
                    None,
                    "missing or wrong access token"
                    if given
                    else "this service asks for an access token to change runs",
                    "Authorization: Bearer <the token printed by `nmkane serve` at start>",
                )
            ],
            headers={"WWW-Authenticate": 'Bearer realm="nmkane"'},
        )
        return await response(scope, receive, send)


_TIMEOUT_BODY = (
    b'{"detail":[{"loc":["body"],"field":"body","msg":"request timeout: the request was not sent '
    b'in time","type":"request_timeout","value":null,"reason":"the request (head and body) was not '
    b'received within the read timeout","allowed":null}]}'
)


def read_deadline_protocol(seconds: float):
    """uvicorn's httptools protocol with a deadline of ``seconds`` on reading each request.

    The clock starts when a connection opens (and again when a keep-alive connection starts
    its next request) and stops when the request's body is complete; at the deadline the
    client gets 408 (if nothing was answered yet) and the connection is closed."""
    from uvicorn.protocols.http.httptools_impl import HttpToolsProtocol

    class ReadDeadlineProtocol(HttpToolsProtocol):
        read_timeout = seconds
        _deadline: asyncio.TimerHandle | None = None

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
            super().connection_lost(exc)

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
