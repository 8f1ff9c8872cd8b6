"""The hostile requests of ``scripts/attack.py``, as raw HTTP/1.1 bytes, and the asyncio client
that sends them: one connection per request (``Connection: close``), the answer read to its end,
every answer put in a class (:func:`classify`: a documented refusal or a server error)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import re
from collections import Counter

SMALL = {"system": "appell-hamel", "t_final": 2}
GRID_10M = {"grid": ["gamma1=0.001:0.002:10000000"]}  # 10⁷ runs in 41 bytes


def http(method: str, path: str, body: bytes = b"", ctype: str | None = "application/json", headers=()) -> bytes:
    """One HTTP/1.1 request as bytes (``Connection: close``: the answer ends with the connection)."""
    head = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", "Connection: close", *headers]
    if ctype:
        head.append(f"Content-Type: {ctype}")
    framed = any(h.lower().startswith(("transfer-encoding", "content-length")) for h in headers)
    if not framed and (body or method in ("POST", "PUT", "PATCH")):
        head.append(f"Content-Length: {len(body)}")
    return ("\r\n".join(head) + "\r\n\r\n").encode("latin-1") + body


def _runs(body) -> bytes:
    return http("POST", "/api/runs", body if isinstance(body, bytes) else json.dumps(body).encode())


def _sweeps(body) -> bytes:
    return http("POST", "/api/sweeps", body if isinstance(body, bytes) else json.dumps(body).encode())


def _out_of_range() -> list[dict]:
    ah = {"system": "appell-hamel"}
    fields = [
        {"dt": -1}, {"dt": 0}, {"dt": 1e-300}, {"dt": "x"}, {"dt": True}, {"dt": None}, {"t_final": -5},
        {"t_final": 0}, {"every": 0}, {"every": -1}, {"every": 2**63}, {"every": 10**30}, {"every": 1.5},
        {"gamma": 1e308}, {"gamma": [[1, 2], [3]]}, {"gamma": [[0.0] * 40] * 40}, {"params": {"rho": -2}},
        {"params": {"nope": 1}}, {"params": []}, {"initial": {"u3": 1}}, {"initial": "x"}, {"integrator": "nope"},
        {"projection": "x" * 1000}, {"rtol": 0}, {"rtol": -1}, {"atol": 1e300}, {"model": "nope"},
        {"switching": "maybe"}, {"projection_iterations": 10**6}, {"rcond_min": -1}, {"max_violation": 1e308},
        {"solve": "nope"}, {"unknown_field": 1}, {"params": {"rho": 1e308}}, {"initial": {"u1": 1e308}},
    ]  # fmt: skip
    huge = [
        {"t_final": 1e9}, {"t_final": 1e308}, {"dt": 1e-9, "t_final": 1e9}, {"every": 10**12, "t_final": 1e6},
        {"t_final": 1e9, "every": 10**9}, {"dt": 1e-7, "t_final": 1e6, "every": 10**6},
    ]  # fmt: skip
    names = ["nope", "../../etc/passwd", "APPELL-HAMEL", "appell-hamel\x00", "a" * 60000, "", "   ", "%s%n", 7]
    return [{**ah, **f} for f in fields + huge] + [{"system": n} for n in names]


def _malformed() -> list[bytes]:
    return [
        b'{"dt": 0.01,', b"{", b"", b"null", b"[]", b'"x"', b"1", b"\xff\xfe\xfd", b'{"system": "\\ud800"}',
        b'{"dt": 0.01} x', b'{"dt": 01}', b"{'dt': 0.01}", b'{"dt": 0.01, "dt": "x"}', b'{"a": "\x00"}',
        b'{"dt": NaN}', b'{"t_final": Infinity}', b'{"gamma": -Infinity}', b'{"dt": 1e999}',
        b'{"params": {"rho": NaN}}', b'{"initial": {"u1": -1e400}}', b'{"gamma1": [[NaN]]}', b"[" * 60000,
        b'{"a":' * 10000 + b"1" + b"}" * 10000, b'{"params": ' + b'{"a": ' * 9000 + b"1" + b"}" * 9001,
        b'{"initial": ' + b"[" * 30000 + b"]" * 30000 + b"}", b'{"every": ' + b"9" * 5000 + b"}",
        b"{" + b" " * 70000 + b"}", b'{"system": "' + b"\\u0000" * 10000 + b'"}',
    ]  # fmt: skip


def _bad_sweeps() -> list[bytes]:
    bodies = [
        GRID_10M,
        {"grid": [f"params.p{i}=0:1:10000000" for i in range(8)], "log_grid": ["initial.q=1:2:10000000"] * 8},
        {"sample": ["gamma1=0:1"], "samples": 10**7}, {"sample": ["gamma1=0:1"], "samples": 10**8},
        {"sample": ["gamma1=0:1"], "samples": 0}, {"sample": ["gamma1=0:1"], "samples": 2, "seed": -1},
        {"sample": ["gamma1=0:1"], "samples": 2, "seed": 2**64}, {"grid": ["nope"]}, {"grid": ["gamma1=1:0:5"]},
        {"grid": ["gamma1=nan:1:3"]}, {"log_grid": ["gamma1=-1:1:3"]}, {"grid": ["gamma1=0:1:-3"]},
        {"settings": {"system": "nope"}, "grid": ["gamma1=0:1:2"]}, {"settings": "x"}, {"grid": []},
        {"grid": ["gamma1=0:1:2"] * 3000}, {"grid": ["gamma1=0:1:1e7"]},
        {"settings": {"dt": 1e-9}, "grid": ["a=0:1:2"]},
    ]  # fmt: skip
    return [_sweeps(b) for b in bodies]


def _bad_http() -> list[bytes]:
    q = [
        "limit=abc", "limit=0", f"limit={10**30}", "offset=-1", f"offset={2**63}", "status=nope",
        "system=" + "x" * 5000, "limit=1&limit=2", "offset=1e3", "limit=%00",
    ]  # fmt: skip
    paths = [
        "/api/runs/%00", "/api/runs/..%2F..%2Fetc%2Fpasswd", "/api/runs/" + "a" * 65, "/api/runs/x.csv",
        "/api/runs/%ff%fe", f"/api/sweeps/x?offset={2**63}", "/api/sweeps/x?limit=0", "/api/sweeps/x.csv",
        "/../../etc/passwd", "/api/runs/%2e%2e/health", "/api/runs/" + "a" * 100_000, "/api/" + "%" * 1000,
    ]  # fmt: skip
    return [
        *(http("GET", f"/api/runs?{x}", ctype=None) for x in q),
        *(http("GET", p, ctype=None) for p in paths),
        *(http(m, "/api/runs", b"{}") for m in ("PUT", "PATCH", "DELETE", "OPTIONS", "TRACE")),
        http("POST", "/api/health", b"{}"), http("DELETE", "/api/runs/nope", ctype=None),
        http("DELETE", "/api/sweeps/x", ctype=None),
        http("GET", "/api/health", ctype=None, headers=["X-Big: " + "a" * 100_000]),
        http("GET", "/api/health", ctype=None, headers=[f"X-H{i}: v" for i in range(5000)]),
        http("POST", "/api/runs", b"{}", headers=["Content-Length: 1000000000000"]),
        http("POST", "/api/runs", b"{}", headers=["Content-Length: -1"]),
        http("POST", "/api/runs", b"{}", headers=["Content-Length: abc"]),
        http("POST", "/api/runs", b"{}", headers=["Content-Length: 2", "Content-Length: 3"]),
        http("POST", "/api/runs", b"2\r\n{}\r\n0\r\n\r\n", headers=["Transfer-Encoding: chunked", "Content-Length: 2"]),
        http("POST", "/api/runs", b"".join(b"10000\r\n" + b" " * 65536 + b"\r\n" for _ in range(32)) + b"0\r\n\r\n",
             headers=["Transfer-Encoding: chunked"]),
        http("POST", "/api/runs", b" " * 8_000_000),
        http("POST", "/api/runs", b'{"dt": 0.01}', ctype="text/plain"),
        http("POST", "/api/runs", b'{"dt": 0.01}', ctype=None),
        http("POST", "/api/runs", '{"dt": 0.01}'.encode("utf-16"), ctype="application/json; charset=utf-16"),
        http("POST", "/api/runs", b"dt=0.01", ctype="application/x-www-form-urlencoded"),
        http("POST", "/api/runs", b"--x\r\n\r\n--x--", ctype="multipart/form-data; boundary=x"),
        b"\x00\x01\x02\r\n\r\n", b"GET\r\n\r\n", b"GET / HTTP/9.9\r\nHost: x\r\n\r\n",
        b"BREW /api/runs HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n",
        b"GET /api/health HTTP/1.1\r\nConnection: close\r\n\r\n",
        b"GET /api/health HTTP/1.1\r\nHost: evil.example\r\nConnection: close\r\n\r\n",
        b"GET /api/health HTTP/1.1\r\nHost: " + b"h" * 10_000 + b"\r\nConnection: close\r\n\r\n",
    ]  # fmt: skip


def hostile_requests(integrators: dict) -> tuple[list[bytes], list[bytes]]:
    """(requests sent in every round, requests sent once: runs that take the wall time, a body
    that never comes)."""
    every_round = [*map(_runs, _out_of_range()), *map(_runs, _malformed()), *_bad_sweeps(), *_bad_http()]
    adaptive = [name for name, kind in integrators.items() if kind != "fixed"] or ["rk45"]
    once = [_runs({"system": "appell-hamel", "integrator": i, "t_final": 1e9}) for i in adaptive]
    once += [_runs({"integrator": "radau", "rtol": 1e-13, "atol": 1e-15, "t_final": 1e4})]
    once += [http("POST", "/api/runs", b'{"dt":', headers=["Content-Length: 100"])]  # the rest never sent
    return every_round, once


async def exchange(port: int, raw: bytes, timeout: float = 120.0, connected=None) -> tuple[int | str, bytes]:
    """Send ``raw`` and read the answer to its end, reading while sending (an answer given before
    the body is all sent, a 413, is read before the connection is reset): (status, or what
    happened instead; body)."""
    try:
        reader, writer = connected or await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), timeout)
    except (OSError, TimeoutError) as e:
        return f"connect: {type(e).__name__}", b""
    data = bytearray()

    async def read() -> None:
        while chunk := await reader.read(1 << 16):
            data.extend(chunk)

    reading = asyncio.ensure_future(read())
    try:
        writer.write(raw)
        with contextlib.suppress(ConnectionError, TimeoutError):  # refused early: its answer is read
            await asyncio.wait_for(writer.drain(), timeout)
        await asyncio.wait_for(reading, timeout)
    except ConnectionError:
        pass
    except TimeoutError:
        return "no answer in time", b""
    finally:
        reading.cancel()
        writer.close()
        with contextlib.suppress(Exception):
            await writer.wait_closed()
    m = re.match(rb"HTTP/1\.[01] (\d{3})", data)
    if m is None:
        return ("reset before an answer" if not data else "not HTTP"), b""
    return int(m.group(1)), bytes(data).split(b"\r\n\r\n", 1)[-1]


def classify(status: int | str, body: bytes) -> str:
    """An answer's class; a 503 is a documented refusal when it says so (uvicorn's connection cap,
    the run queue's or the sweeps' ``overloaded``), any other 5xx is a server error."""
    if isinstance(status, str):
        return f"transport: {status}"
    if status == 503 and body.strip() == b"Service Unavailable":
        return "503 connection cap"
    if status == 503 and b'"type":"overloaded"' in body:
        return "503 queue full"
    return "5xx server error" if status >= 500 else f"{status // 100}xx"


async def burst(port: int, requests: list[bytes], concurrency: int) -> Counter:
    gate = asyncio.Semaphore(concurrency)

    async def one(raw: bytes) -> tuple[str, bytes, int]:
        async with gate:
            status, body = await exchange(port, raw)
        return classify(status, body), raw.split(b"\r\n", 1)[0][:60], len(raw)

    seen: Counter = Counter()
    for kind, head, size in await asyncio.gather(*(one(r) for r in requests)):
        seen[kind] += 1
        if kind == "5xx server error" or kind.startswith("transport"):
            print(f"attack:   {kind} for {head!r}… ({size:,} bytes)", flush=True)
    return seen


async def flood(port: int, n: int) -> Counter:
    """``n`` connections opened at once, then each sends its request (a health check or a small run)."""
    opened = await asyncio.gather(
        *(asyncio.open_connection("127.0.0.1", port) for _ in range(n)), return_exceptions=True
    )
    body = json.dumps(SMALL).encode()
    todo = [
        exchange(
            port, http("GET", "/api/health", ctype=None) if i % 2 else http("POST", "/api/runs", body), connected=c
        )
        for i, c in enumerate(opened)
        if not isinstance(c, BaseException)
    ]
    seen = Counter(classify(*answer) for answer in await asyncio.gather(*todo))
    seen["transport: connect refused"] += sum(isinstance(c, BaseException) for c in opened)
    return +seen
