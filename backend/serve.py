"""``nmkane serve``: the REST API (uvicorn) and the 3D web app (viser) side by side.

This is the one place that composes the faces.  The web app is not imported by name: it
is found through the entry-point group ``nmkane.apps`` (``web = "web.app:launch_app"`` in
pyproject.toml), so the service and the web app do not import each other.  An app entry
is a callable ``launch_app(host, port, **options)`` returning a handle with ``.port`` and
``.stop()``.  viser runs its own websocket server on its own port, so the two are separate
servers in one process: uvicorn in a thread, the web app in its own threads, and the main
thread waiting for Ctrl-C or SIGTERM, then stopping both.
"""

from __future__ import annotations

import logging
import signal
import threading
import time
from importlib.metadata import entry_points
from typing import Any, Callable

import uvicorn

from .app import create_app
from .config import Settings

__all__ = ["serve", "APP_GROUP"]

APP_GROUP = "nmkane.apps"

log = logging.getLogger("nmkane.serve")


def _start_api(host: str, port: int, settings: Settings) -> tuple[uvicorn.Server, threading.Thread, int]:
    config = uvicorn.Config(create_app(settings), host=host, port=port, log_level="warning",
                            lifespan="on", server_header=False,
                            # let runs in flight finish (each is stored before its 201), within bounds
                            timeout_graceful_shutdown=int(settings.max_wall_time_s) + 5)
    server = uvicorn.Server(config)
    thread = threading.Thread(target=server.run, name="nmkane-api", daemon=True)
    thread.start()
    while not server.started and thread.is_alive():     # lifespan (kernel warm-up) runs first
        time.sleep(0.05)
    if not server.started:
        thread.join(1)
        raise SystemExit(f"nmkane serve: the REST API could not start on {host}:{port} "
                         "(is the port in use? see the message above)")
    bound = server.servers[0].sockets[0].getsockname()[1] if server.servers else port
    return server, thread, bound


def _stop_api(server: uvicorn.Server, thread: threading.Thread) -> None:
    server.should_exit = True
    thread.join(server.config.timeout_graceful_shutdown + 10)


def _web_app() -> Callable[..., Any]:
    """The web app's launcher, from the ``nmkane.apps`` entry-point group."""
    found = [ep for ep in entry_points(group=APP_GROUP) if ep.name == "web"]
    if not found:
        raise ImportError(f"no 'web' entry in the {APP_GROUP} entry-point group (is nmkane installed?)")
    return found[0].load()


def serve(host: str = "127.0.0.1", api_port: int = 8000, viser_port: int = 8080, web: bool = True,
          settings: Settings | None = None, app_options: dict | None = None) -> None:
    """Serve until SIGINT or SIGTERM, then stop both servers. Binds to loopback by default.

    Port 0 picks a free port (the URLs printed show the real ones).  ``app_options`` are
    passed to the web app's ``launch_app`` (e.g. ``scene``: the system new browsers open on).

    In the main thread, ``serve`` handles SIGINT and SIGTERM itself.  Once a signal has
    asked it to stop, further SIGINT/SIGTERM are ignored (``SIG_IGN``) from then on: the
    stop is under way and a repeat cannot hasten it.  Restoring the previous handlers would
    let a late signal of a burst kill the process half-way through its exit (status −15
    after a clean stop), and so would a Python-level handler, because the interpreter
    resets those to the default action while it finalizes; an ignored signal stays
    ignored.  The previous handlers come back only when ``serve`` returns for another
    reason (the API stopped).
    """
    settings = settings if settings is not None else Settings()
    # The handler only appends to a list: no lock.  (It used to call Event.set(); a second
    # signal arriving while the first handler held the Event's lock — Ctrl-C twice, or a
    # supervisor forwarding SIGTERM on top of its own — deadlocked the main thread for good.)
    stopping: list[int] = []
    in_main = threading.current_thread() is threading.main_thread()
    previous = {}
    if in_main:
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous[sig] = signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    handle = None
    server = thread = None
    try:
        server, thread, port = _start_api(host, api_port, settings)
        url_host = f"[{host}]" if ":" in host else host
        print(f"nmkane REST API    http://{url_host}:{port}/api   (docs: http://{url_host}:{port}/docs; "
              f"runs stored in {settings.database})", flush=True)
        if web:
            try:
                launch_app = _web_app()
            except ImportError as e:        # the 3D web app is optional for the API
                log.warning("3D web app not available (%s); serving the REST API only", e)
                print(f"nmkane: 3D web app not available ({e}); serving the REST API only", flush=True)
            else:
                handle = launch_app(host, viser_port, **(app_options or {}))
                print(f"nmkane 3D web app  http://{url_host}:{handle.port}/", flush=True)
        print("press Ctrl-C to stop", flush=True)
        while not stopping:
            time.sleep(0.2)                  # a signal interrupts the sleep; its handler runs here
            if not thread.is_alive():
                log.error("the REST API stopped unexpectedly")
                break
    finally:
        if handle is not None:
            try:
                handle.stop()
            except Exception:                       # keep stopping the API
                log.exception("stopping the 3D web app failed")
        if server is not None:
            _stop_api(server, thread)
        for sig, h in previous.items():   # see the docstring: after a signal stop, repeats are ignored
            signal.signal(sig, signal.SIG_IGN if stopping else h)
        if server is not None:
            print("nmkane: stopped", flush=True)
