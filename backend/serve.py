"""``nmkane serve``: the REST API (uvicorn) and the 3D web app (viser) side by side.

This is the one place that composes the faces.  The web app is not imported by name: it
is found through the entry-point group ``nmkane.apps`` (``web = "web.app:launch_app"`` in
pyproject.toml), so the service and the web app do not import each other.  An app entry
is a callable ``launch_app(host, port, **options)`` returning a handle with ``.port`` and
``.stop()``.  viser runs its own websocket server on its own port, so the two are separate
servers: uvicorn in a thread of this process, the web app in a child process of its own
(:class:`AppProcess`, ``multiprocessing`` spawn), and the main thread waiting for Ctrl-C or
SIGTERM, then stopping both.  Why a process: the web app animates every browser's scene
many times a second in Python, and in one process it shared the GIL with the REST API —
measured, 8 browsers raised REST p50 from 11 to 109 ms.  The child ignores SIGINT (a
Ctrl-C reaches the whole process group; the parent stops it in order) and stops when the
parent says so or when the parent is gone (its end of the pipe closes).

Exposure: on a loopback address (the default) nothing changes.  Bound to another address,
``serve`` makes an access token (``secrets``) and prints it, as Jupyter does: REST writes
need ``Authorization: Bearer <token>``, the web app's URL carries ``?token=``; ``auth=False``
(``--no-auth``) serves without one.  Both servers answer only to allowed host names
(loopback names, the bound address, ``allow_hosts``), and the web app's websocket only to
pages of its own origin.

Stopping while kernels are prepared in the background (a first start derives each system's
model and compiles its C functions): the warm-up threads stop between steps, and a SIGTERM or
Ctrl-C during the warm-up that comes before the API answers ends it after the step under way.
``serve`` waits ``WARM_JOIN_S`` for the threads and, if one is still busy (a long derivation),
ends the process with ``os._exit(0)`` once everything else is stopped and flushed (nothing is
left to tear down: the store is closed).
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import logging
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from importlib.metadata import entry_points
from typing import Any

import uvicorn

from nmkane_core.access import allowed_host_names, is_loopback, new_token
from nmkane_core.errors import NmkaneError

from .app import create_app
from .config import Settings
from .guard import read_deadline_protocol
from .store import RunStore

__all__ = ["serve", "AppProcess", "APP_GROUP", "WARM_JOIN_S"]

APP_GROUP = "nmkane.apps"
WARM_JOIN_S = 5.0  # stop: how long to wait for a background warm-up step before abandoning it
WARM_THREAD_PREFIX = "nmkane-warm"

log = logging.getLogger("nmkane.serve")


#: open connections to the REST API (idle keep-alive ones included; uvicorn counts a new one with
#: the open ones, so 255 are served and the next is answered 503); each slow reader holds about
#: 1 MB (a piece of the document and the decompressor's window) until the read deadline
MAX_CONNECTIONS = 256


def _start_api(
    host: str, port: int, settings: Settings, stopping: list[int] | None = None
) -> tuple[uvicorn.Server, threading.Thread, int]:
    """Start the REST API in a thread; return once it answers (after the kernel warm-up).  A
    stop signal meanwhile (``stopping``) ends the warm-up after the step under way."""
    app = create_app(settings)
    config = uvicorn.Config(
        app,
        host=host,
        port=port,
        log_level="warning",
        lifespan="on",
        server_header=False,
        # a client must send each request (head and body) within read_timeout_s, and take some
        # of an answer waiting for it within as long (a client that stops reading is dropped)
        http=read_deadline_protocol(settings.read_timeout_s),
        # at most this many connections (and requests in progress): past it uvicorn answers 503
        limit_concurrency=MAX_CONNECTIONS,
        # let runs in flight finish (each is stored before its 201), within bounds
        timeout_graceful_shutdown=int(settings.max_wall_time_s) + 5,
    )
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="nmkane-api", daemon=True)
    thread.start()
    interrupted = False
    while not server.started and thread.is_alive():  # lifespan (kernel warm-up) runs first
        if stopping and not interrupted:  # SIGTERM or Ctrl-C during the warm-up
            app.state.service.interrupt_warm()
            interrupted = True
        time.sleep(0.05)
    if not server.started:
        thread.join(1)
        raise SystemExit(
            f"nmkane serve: the REST API could not start on {host}:{port} (is the port in use? see the message above)"
        )
    bound = server.servers[0].sockets[0].getsockname()[1] if server.servers else port
    return server, thread, bound


#: glibc's ``mallopt`` option and the size from which a block is mapped from the system (and
#: returned to it when freed); see :func:`_large_blocks_returned`
M_MMAP_THRESHOLD, MMAP_THRESHOLD = -3, 1024 * 1024


def _large_blocks_returned() -> None:
    """Hold glibc's mmap threshold at 1 MB in this process.  By default glibc raises it each time
    a mapped block is freed (up to 32 MB); then a decompressed run document or a CSV's columns are
    carved from a thread's arena, and stay there when freed: ``malloc_trim`` does not return an
    arena's free top.  Measured with ``scripts/attack.py``: 10 clients that read nothing of a
    21 MB run's CSV left the service 300-400 MiB larger for good (121 → 521 MiB); with the
    threshold held, 93 → 133 MiB.  A usual run's document (570 kB) stays below it, in the arenas,
    as before.  Nothing where the C library is not glibc."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL("libc.so.6").mallopt(M_MMAP_THRESHOLD, MMAP_THRESHOLD)


def _check_store(settings: Settings) -> None:
    """Open the run store read-write once before anything starts: one that cannot be (a folder
    in its place, a damaged or read-only file) raises its :class:`~backend.store.StoreError`,
    one line naming the file and what to do (``nmkane serve`` prints it and exits 2), instead
    of failing inside the API's start with a traceback."""
    RunStore(settings.database, settings.store_cap).close()


def _stop_api(server: uvicorn.Server, thread: threading.Thread) -> None:
    server.should_exit = True
    thread.join((server.config.timeout_graceful_shutdown or 0) + 10)


def _web_app() -> Callable[..., Any]:
    """The web app's launcher, from the ``nmkane.apps`` entry-point group."""
    found = [ep for ep in entry_points(group=APP_GROUP) if ep.name == "web"]
    if not found:
        raise ImportError(f"no 'web' entry in the {APP_GROUP} entry-point group (is nmkane installed?)")
    return found[0].load()


def _check_web_app() -> None:
    """ImportError if the web app's entry or its module cannot be found (without importing
    it here: the child process does)."""
    found = [ep for ep in entry_points(group=APP_GROUP) if ep.name == "web"]
    if not found:
        raise ImportError(f"no 'web' entry in the {APP_GROUP} entry-point group (is nmkane installed?)")
    module = found[0].module
    try:
        spec = importlib.util.find_spec(module)
    except (ImportError, ValueError) as e:
        raise ImportError(f"{module}: {e}") from None
    if spec is None:
        raise ImportError(f"no module named {module!r}")


def _app_child(conn, host: str, port: int, options: dict) -> None:
    """The child process of :class:`AppProcess`: launch the web app, report its port and URL
    (or the error), serve until told to stop or until the parent is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C: the parent stops us in order
    try:
        handle = _web_app()(host, port, **options)
    except BaseException as e:  # reported to the parent, which serves the REST API alone
        conn.send(("error", f"{type(e).__name__}: {e}"))
        return
    conn.send(("ok", handle.port, getattr(handle, "url", None)))
    try:
        conn.recv()  # "stop", or EOFError: the parent is gone
    except (EOFError, OSError):
        pass
    finally:
        handle.stop()
        _abandon_compilation(quiet=True)  # the web app warms kernels in the background too


class WebAppFailed(NmkaneError, RuntimeError):
    """The web app's process did not start (``nmkane serve`` says why on one line, exit 2)."""


class AppProcess:
    """The web app in a child process: ``.port``, ``.url`` and ``.stop()`` like the app's own
    handle.  ``timeout_s``: how long to wait for it to start (it imports viser and numpy)."""

    def __init__(self, host: str, port: int, options: dict, timeout_s: float = 300.0):
        ctx = multiprocessing.get_context("spawn")  # no fork of a process with threads
        self._conn, child_conn = ctx.Pipe()
        self.process = ctx.Process(
            target=_app_child, args=(child_conn, host, port, options), name="nmkane-web", daemon=True
        )
        self.process.start()
        child_conn.close()
        if not self._conn.poll(timeout_s):
            self.stop()
            raise WebAppFailed(f"the 3D web app did not start within {timeout_s:.0f} s")
        try:
            answer = self._conn.recv()
        except EOFError:
            self.process.join(5)
            raise WebAppFailed(f"the 3D web app's process ended at start (status {self.process.exitcode})") from None
        if answer[0] != "ok":
            self.process.join(10)
            raise WebAppFailed(f"the 3D web app could not start: {answer[1]}")
        _, self.port, self.url = answer

    def stop(self, timeout_s: float = 20.0) -> None:
        """Ask the child to stop and wait for it (then terminate, then kill)."""
        with contextlib.suppress(OSError, ValueError):  # the child is gone already
            self._conn.send("stop")
        self.process.join(timeout_s)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(5)
        self._conn.close()


def _abandon_compilation(quiet: bool = False, failure: BaseException | None = None) -> None:
    """Wait ``WARM_JOIN_S`` for background warm-up threads; if one is still running, end the
    process now (see the module docstring).
    ``quiet``: print nothing (the web app's child process).  ``failure``: why the service is
    stopping, when it failed (the web app did not start): printed on one line, and the process
    ends with status 1 instead of 0 (it ended 0, silently, with the reason lost)."""
    deadline = time.monotonic() + WARM_JOIN_S
    for t in threading.enumerate():
        if t.name.startswith(WARM_THREAD_PREFIX) and t is not threading.current_thread():
            t.join(max(0.0, deadline - time.monotonic()))
    busy = [t.name for t in threading.enumerate() if t.name.startswith(WARM_THREAD_PREFIX) and t.is_alive()]
    if busy:
        if failure is not None:
            print(f"nmkane serve: error: {' '.join(str(failure).split()) or type(failure).__name__}", file=sys.stderr)
        elif not quiet:
            print(
                "nmkane: stopped (a background kernel warm-up was abandoned; the next start prepares what is missing)",
                flush=True,
            )
        sys.stderr.flush()
        logging.shutdown()
        os._exit(0 if failure is None else 1)


def _auth(host: str, auth: bool, settings: Settings) -> str | None:
    """The access token (None: none asked for): loopback needs none, another address does unless
    ``auth`` is False; an NMKANE_TOKEN in the settings is used as given."""
    if settings.token is not None:
        return settings.token
    if is_loopback(host) or not auth:
        return None
    return new_token()


def _exposed(settings: Settings, host: str, auth: bool, allow_hosts: tuple[str, ...]) -> Settings:
    """The settings for serving on ``host``: the token (see :func:`_auth`) and every allowed host
    name (loopback names, ``host``, the configured and the ``allow_hosts`` names)."""
    token = _auth(host, auth, settings)
    if not is_loopback(host) and token is None:
        print(
            f"nmkane: WARNING: serving {host} without an access token (--no-auth): anyone who can reach "
            "these ports can run and delete runs",
            flush=True,
        )
    allowed = allowed_host_names(host, (*settings.allowed_hosts, *allow_hosts))
    return settings.model_copy(update={"token": token, "allowed_hosts": allowed})


def _url_host(host: str) -> str:
    return f"[{host}]" if ":" in host else host


def _announce_api(host: str, port: int, settings: Settings) -> None:
    url = f"http://{_url_host(host)}:{port}"
    print(f"nmkane REST API    {url}/api   (docs: {url}/docs; runs stored in {settings.database})", flush=True)
    if settings.token:
        print(
            f"nmkane access token {settings.token}   (REST runs and sweeps: 'Authorization: Bearer <token>')",
            flush=True,
        )


def _start_web(host: str, port: int, settings: Settings, options: dict, in_process: bool):
    """Start the web app (a child process unless ``in_process``) and print its URL; None when
    it is not installed (the REST API serves alone)."""
    try:
        _web_app() if in_process else _check_web_app()
    except ImportError as e:  # the 3D web app is optional for the API
        log.warning("3D web app not available (%s); serving the REST API only", e)
        print(f"nmkane: 3D web app not available ({e}); serving the REST API only", flush=True)
        return None
    options = {**options, "token": settings.token, "allowed_hosts": settings.allowed_hosts}
    handle = _web_app()(host, port, **options) if in_process else AppProcess(host, port, options)
    query = f"?token={settings.token}" if settings.token else ""
    url = getattr(handle, "url", None) or f"http://{_url_host(host)}:{handle.port}/{query}"
    print(f"nmkane 3D web app  {url}", flush=True)
    return handle


def _catch_stop_signals(stopping: list[int]) -> dict:
    """In the main thread, SIGINT and SIGTERM append to ``stopping``; returns the previous handlers.

    The handler only appends to a list: no lock.  (It used to call Event.set(); a second
    signal arriving while the first handler held the Event's lock — Ctrl-C twice, or a
    supervisor forwarding SIGTERM on top of its own — deadlocked the main thread for good.)"""
    previous = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    return previous


def _wait_for_stop(stopping: list[int], api_thread: threading.Thread) -> None:
    print("press Ctrl-C to stop", flush=True)
    while not stopping:
        time.sleep(0.2)  # a signal interrupts the sleep; its handler runs here
        if not api_thread.is_alive():
            log.error("the REST API stopped unexpectedly")
            return


def _stop_all(handle, server: uvicorn.Server | None, thread: threading.Thread | None) -> None:
    """Stop the web app, then the REST API (runs in flight are stored first)."""
    if handle is not None:
        try:
            handle.stop()
        except Exception:  # keep stopping the API
            log.exception("stopping the 3D web app failed")
    if server is not None and thread is not None:
        _stop_api(server, thread)


def serve(
    host: str = "127.0.0.1",
    api_port: int = 8000,
    viser_port: int = 8080,
    web: bool = True,
    settings: Settings | None = None,
    allow_hosts: tuple[str, ...] = (),
    auth: bool = True,
    max_sessions: int | None = None,
    app_options: dict | None = None,
    app_process: bool = True,
) -> None:
    """Serve until SIGINT or SIGTERM, then stop both servers. Binds to loopback by default.

    Port 0 picks a free port (the URLs printed show the real ones).  ``allow_hosts``: host
    names clients may use besides the loopback names and ``host``; ``auth``: on a
    non-loopback ``host``, ask for an access token (printed at start); ``max_sessions``:
    browsers the web app serves at once (None: its default); ``app_options``: passed on to
    the web app's ``launch_app`` (e.g. ``scene``: the system new browsers open on);
    ``app_process``: run the web app in a child process (:class:`AppProcess`, the default)
    rather than in threads of this one.

    In the main thread, ``serve`` handles SIGINT and SIGTERM itself.  Once a signal has
    asked it to stop, further SIGINT/SIGTERM are ignored (``SIG_IGN``) from then on: the
    stop is under way and a repeat cannot hasten it.  Restoring the previous handlers would
    let a late signal of a burst kill the process half-way through its exit (status −15
    after a clean stop), and so would a Python-level handler, because the interpreter
    resets those to the default action while it finalizes; an ignored signal stays
    ignored.  The previous handlers come back only when ``serve`` returns for another
    reason (the API stopped).
    """
    settings = _exposed(settings if settings is not None else Settings(), host, auth, allow_hosts)
    _large_blocks_returned()
    _check_store(settings)
    options = dict(app_options or {})
    if max_sessions is not None:
        options["max_sessions"] = max_sessions
    stopping: list[int] = []
    previous = _catch_stop_signals(stopping)
    handle = server = thread = None
    failure: BaseException | None = None
    try:
        server, thread, port = _start_api(host, api_port, settings, stopping)
        if stopping:  # asked to stop while the service started
            return
        _announce_api(host, port, settings)
        if web:
            handle = _start_web(host, viser_port, settings, options, in_process=not app_process)
        _wait_for_stop(stopping, thread)
    except Exception as e:  # the web app did not start, ...: said on the way out, never an exit 0
        failure = e
        raise
    finally:
        _stop_all(handle, server, thread)
        for sig, h in previous.items():  # see the docstring: after a signal stop, repeats are ignored
            signal.signal(sig, signal.SIG_IGN if stopping else h)
        if server is not None:
            _abandon_compilation(failure=failure)
            print("nmkane: stopped", flush=True)
