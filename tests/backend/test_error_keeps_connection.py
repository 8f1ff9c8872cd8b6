"""A 500 never resets the next request on the same connection (issue 44, item 4).

An unexpected exception in a route answers 500 in the one error shape (``on_unexpected``);
starlette then raises the exception again to the server, and uvicorn closes the connection
after a response it has sent.  The client, told nothing, sent its next request on that
keep-alive connection and got a reset.  Now the 500 says ``Connection: close``, so a client
opens a new connection for its next request; a request that does not fail keeps the
connection open as before.

The service is uvicorn in a thread with the protocol ``nmkane serve`` uses, on a port of its
own; the failing routes are added to the app only here, through the app factory.  The client
is a raw socket that sends two requests, one after the other, on one connection.
"""

from __future__ import annotations

import socket
import threading
import time

import pytest
import uvicorn
from fastapi.responses import StreamingResponse

from backend import Settings, create_app
from backend.guard import read_deadline_protocol


@pytest.fixture(scope="module")
def port(tmp_path_factory):
    app = create_app(Settings(data_dir=tmp_path_factory.mktemp("conn"), warm_kernels=False))

    @app.get("/test/boom")
    def boom():
        raise RuntimeError("a bug in a route")

    @app.get("/test/boom-in-body")
    def boom_in_body():
        def chunks():
            yield b"t,x\n0,1\n"
            raise RuntimeError("a bug while streaming")

        return StreamingResponse(chunks(), media_type="text/csv")

    config = uvicorn.Config(
        app, host="127.0.0.1", port=0, log_level="critical", lifespan="on", http=read_deadline_protocol(10.0)
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, daemon=True)
    thread.start()
    deadline = time.monotonic() + 60
    while not server.started and thread.is_alive() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert server.started
    try:
        yield server.servers[0].sockets[0].getsockname()[1]
    finally:
        server.should_exit = True
        thread.join(30)


def _request(sock: socket.socket, path: str) -> None:
    sock.sendall(f"GET {path} HTTP/1.1\r\nHost: localhost\r\n\r\n".encode())


def _response(sock: socket.socket) -> tuple[int, dict[str, str], bytes] | None:
    """One response read from ``sock`` (by its Content-Length), or None when the connection
    was closed or reset before any of it came."""
    data = b""
    try:
        while b"\r\n\r\n" not in data:
            chunk = sock.recv(65536)
            if not chunk:
                return None
            data += chunk
        head, body = data.split(b"\r\n\r\n", 1)
        lines = head.decode("latin-1").split("\r\n")
        headers = {k.strip().lower(): v.strip() for k, v in (line.split(":", 1) for line in lines[1:])}
        while len(body) < int(headers.get("content-length", "0")):
            chunk = sock.recv(65536)
            if not chunk:
                break
            body += chunk
    except ConnectionResetError:
        return None
    return int(lines[0].split()[1]), headers, body


def _connect(port: int) -> socket.socket:
    sock = socket.create_connection(("127.0.0.1", port), timeout=10)
    return sock


def test_a_500_says_connection_close_and_the_next_request_on_that_connection_is_not_reset(port):
    with _connect(port) as sock:
        _request(sock, "/test/boom")
        first = _response(sock)
        assert first is not None
        status, headers, body = first
        assert status == 500 and b'"internal_error"' in body  # the one error shape
        if headers.get("connection", "").lower() != "close":
            # kept open as far as the client can tell: the next request must be answered
            _request(sock, "/api/health")
            assert _response(sock) is not None, "the 500 did not say Connection: close, and the connection was dropped"
        else:
            assert sock.recv(1) == b""  # closed, as announced: a client opens a new one
    with _connect(port) as sock:  # the service itself is fine
        _request(sock, "/api/health")
        again = _response(sock)
        assert again is not None and again[0] == 200


def test_a_request_that_does_not_fail_keeps_the_connection(port):
    with _connect(port) as sock:
        for _ in range(2):
            _request(sock, "/api/health")
            answered = _response(sock)
            assert answered is not None and answered[0] == 200
            assert answered[1].get("connection", "").lower() != "close"


def test_a_failure_inside_a_streamed_body_ends_that_connection_not_the_service(port):
    """Once the 200 and part of the body are sent nothing can be said any more: the answer is cut
    short (its chunked body never ends) and the connection closed, so the client knows it is
    incomplete; the next connection is served."""
    with _connect(port) as sock:
        _request(sock, "/test/boom-in-body")
        data = b""
        try:
            while chunk := sock.recv(65536):
                data += chunk
        except ConnectionResetError:
            pass
    assert data.startswith(b"HTTP/1.1 200") and b"0,1" in data
    assert not data.endswith(b"0\r\n\r\n")  # no last chunk: incomplete, as the client sees
    with _connect(port) as sock:
        _request(sock, "/api/health")
        again = _response(sock)
        assert again is not None and again[0] == 200
