"""Helpers shared by the tests: server processes on ports they pick themselves, optional dependencies."""

from __future__ import annotations

import asyncio
import concurrent.futures
import re
import signal
import socket
import subprocess
import threading
import time
from pathlib import Path

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"  # the load and measurement scripts
REST_URL = re.compile(r"nmkane REST API\s+http://[^/\s]+:(\d+)/api")
WEB_URL = re.compile(r"nmkane 3D web app\s+http://[^/\s]+:(\d+)/")


class ServerProcess:
    """A server started by a test, its standard output (and error) read line by line in a thread,
    so that the pipe never fills and blocks it.  Servers bind port 0 and print the port they got
    (``nmkane serve``, ``python -m backend``): a port picked by the test and bound later by the
    server could be taken meanwhile by another process (xdist runs two at once)."""

    def __init__(self, args: list[str], env: dict | None = None, cwd=None):
        self.proc = subprocess.Popen(
            args,
            env=env,
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        self.lines: list[str] = []
        self._changed = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._changed:
                self.lines.append(line)
                self._changed.notify_all()
        with self._changed:
            self._changed.notify_all()

    @property
    def output(self) -> str:
        with self._changed:
            return "".join(self.lines)

    def wait_for(self, pattern: str | re.Pattern, timeout: float = 600.0) -> re.Match:
        """The first output line matching ``pattern``, waiting for it up to ``timeout`` s (a cold
        kernel cache compiles first); fails with the output when the server exits without it."""
        rx = re.compile(pattern) if isinstance(pattern, str) else pattern
        deadline = time.monotonic() + timeout
        seen = 0
        with self._changed:
            while True:
                for line in self.lines[seen:]:
                    if m := rx.search(line):
                        return m
                seen = len(self.lines)
                if not self._reader.is_alive() or time.monotonic() > deadline:
                    break
                self._changed.wait(max(0.0, min(1.0, deadline - time.monotonic())))
        self.proc.kill()
        raise AssertionError(f"no line matching {rx.pattern!r} in:\n{self.output}")

    def port(self, pattern: re.Pattern = REST_URL, timeout: float = 600.0) -> int:
        return int(self.wait_for(pattern, timeout).group(1))

    def stop(self, sig: int = signal.SIGTERM, timeout: float = 60.0) -> tuple[int, str]:
        """Send ``sig``, wait for the exit; (exit status, the whole output)."""
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(10)
            raise AssertionError(
                f"the server did not stop within {timeout:g} s after signal {sig}:\n{self.output}"
            ) from None
        self._reader.join(10)
        return code, self.output

    def kill(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(10)
        self._reader.join(10)


def until(condition, timeout: float, every: float = 0.1) -> bool:
    """Poll ``condition()`` until it holds or ``timeout`` s pass; whether it held (a wait on an
    event, never a fixed sleep standing for one)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if condition():
            return True
        time.sleep(every)
    return bool(condition())


def non_reader(port: int, path: str) -> socket.socket:
    """A client that sent ``GET path`` to the service on ``port`` and reads nothing (a 4 kB
    receive buffer)."""
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    sock.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n".encode())
    return sock


def held_connections(port: int, clients: set[int]) -> int:
    """How many connections from the local ports ``clients`` the service on ``port`` still holds
    (Linux /proc/net/tcp: a socket the process has closed, its unsent bytes still queued by the
    kernel, has no inode)."""
    n = 0
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        f = line.split()
        local, remote = (int(x.split(":")[1], 16) for x in (f[1], f[2]))
        n += local == port and remote in clients and f[9] != "0"
    return n


def rss_mib(pid: int) -> float:
    """The resident memory of process ``pid``, MiB (Linux /proc)."""
    with open(f"/proc/{pid}/status") as f:
        return int(f.read().split("VmRSS:")[1].split()[0]) / 1024


def run_coroutine(coro):
    """``asyncio.run(coro)`` in a thread of its own: a test worker that ran the browser tests
    keeps their Playwright session, whose event loop runs in the main thread (asyncio.run
    there raises "cannot be called from a running event loop")."""
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, coro).result()


def start_backend(db, env: dict | None = None) -> tuple[ServerProcess, int]:
    """``python -m backend`` (the REST API alone) with the store ``db`` on a port of its own
    choosing; the server and its port once it answers (a cold kernel cache compiles first)."""
    import os
    import sys

    import httpx

    env = {**os.environ, "PYTHONUNBUFFERED": "1", **(env or {})}
    server = ServerProcess([sys.executable, "-m", "backend", "--port", "0", "--db", str(db)], env=env)
    port = server.port(timeout=600)
    server.wait_for("Ctrl-C")  # serving
    assert httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=10).status_code == 200
    return server, port


def require(module: str):
    """Import an optional test dependency: skipped on a developer machine without it, an error
    under CI (CI=true), where `make test` installs every extra and nothing may silently skip."""
    import importlib
    import os

    import pytest

    if os.environ.get("CI") == "true":
        return importlib.import_module(module)
    return pytest.importorskip(module)


def require_compiler() -> None:
    """A C compiler (kernel/core.py builds the compiled core with it, kernel/native.py each model's
    functions; nmkane runs nothing without one): skipped on a developer machine without one, an
    error under CI (``.ci/run`` installs gcc), where nothing may silently skip."""
    import os

    import pytest

    from nmkane_core.kernel import native

    if native.compiler() is None:
        if os.environ.get("CI") == "true":
            raise RuntimeError("CI=true but no C compiler: .ci/run must install gcc")
        pytest.skip("no C compiler on this machine (cc, gcc or clang)", allow_module_level=True)


def require_browser():
    """Chromium's path and Playwright's ``sync_playwright`` for a browser test module: skipped on
    a developer machine without them, an error under CI (``.ci/run`` installs Chromium)."""
    import os

    import pytest

    from web.screenshot import chromium_path

    in_ci = os.environ.get("CI") == "true"
    chromium = chromium_path()
    if chromium is None:
        if in_ci:
            raise RuntimeError("CI=true but Chromium is not installed: .ci/run must `apt-get install -y chromium`")
        pytest.skip("headless Chromium not installed (apt-get install chromium) — skipped", allow_module_level=True)
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        if in_ci:
            raise
        pytest.skip("playwright not installed (pip install playwright) — skipped", allow_module_level=True)
    return chromium, sync_playwright
