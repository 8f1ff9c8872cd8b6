"""Serve the REST API (uvicorn) and the 3D web app (viser) together; stop both on Ctrl-C."""

from __future__ import annotations

import logging
import signal
import threading
import time

import uvicorn

from .app import create_app
from .config import Settings

log = logging.getLogger("nmkane.serve")


def serve(host: str = "127.0.0.1", api_port: int = 8000, viser_port: int = 8080, web: bool = True,
          settings: Settings | None = None) -> None:
    """Run until SIGINT/SIGTERM. Binds to loopback unless told otherwise."""
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    app = create_app(settings or Settings())
    config = uvicorn.Config(app, host=host, port=api_port, log_level="warning", lifespan="on")
    server = uvicorn.Server(config)
    server.install_signal_handlers = lambda: None      # the main thread handles signals
    thread = threading.Thread(target=server.run, name="uvicorn", daemon=True)
    thread.start()
    while not server.started and thread.is_alive() and not stop.is_set():
        time.sleep(0.05)
    if not thread.is_alive():
        raise SystemExit(f"nmkane serve: the REST service could not start on {host}:{api_port}")
    port = server.servers[0].sockets[0].getsockname()[1] if server.servers else api_port
    print(f"nmkane REST API   http://{host}:{port}/api   (docs: http://{host}:{port}/docs)", flush=True)
    handle = None
    if web:
        try:
            from web.app import launch
        except ImportError as e:  # the web app is optional for the API
            print(f"nmkane: 3D web app not available ({e}); serving the REST API only", flush=True)
        else:
            handle = launch(host, viser_port)
            print(f"nmkane 3D web app http://{host}:{handle.port}/", flush=True)
    print("press Ctrl-C to stop", flush=True)
    try:
        while not stop.wait(0.5):
            if not thread.is_alive():
                break
    finally:
        if handle is not None:
            handle.stop()
        server.should_exit = True
        thread.join(10)
        print("nmkane: stopped", flush=True)
