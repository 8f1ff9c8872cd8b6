"""``serve()``: the REST API and the 3D web app side by side, both stopped by SIGTERM/Ctrl-C.

The servers bind port 0 and the tests read the ports from what ``serve`` prints (a port picked
by the test and bound later by the server could be taken by another process in between)."""

import os
import signal
import socket
import sys
import time

import httpx
import pytest

from tests._helpers import REST_URL, WEB_URL, ServerProcess


def _serve(tmp_path, code, warm=True):
    """``serve`` in a child process; ``warm=False``: without the kernel warm-up (NMKANE_WARM_KERNELS=0)
    where the test's claim is not about it — the warm-up loads every loop before the port is bound."""
    env = {**os.environ, "NMKANE_DB": str(tmp_path / "runs.sqlite3"), "PYTHONUNBUFFERED": "1"}
    if not warm:
        env["NMKANE_WARM_KERNELS"] = "0"
    return ServerProcess([sys.executable, "-c", code], env=env)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_serve_starts_api_and_web_app_and_stops_both(tmp_path, sig):
    # the warm-up (every system's loops loaded before the ports are bound) once, with SIGTERM
    code = "from backend.serve import serve; serve(api_port=0, viser_port=0)"
    server = _serve(tmp_path, code, warm=sig == signal.SIGTERM)
    api, ui = server.port(REST_URL), server.port(WEB_URL)
    server.wait_for("Ctrl-C")
    assert f"http://127.0.0.1:{api}/docs" in server.output
    assert httpx.get(f"http://127.0.0.1:{api}/api/health", timeout=5).json()["status"] == "ok"
    assert httpx.get(f"http://127.0.0.1:{ui}/", timeout=5).status_code == 200
    code, out = server.stop(sig, timeout=30)
    assert code == 0 and "stopped" in out, out
    for port in (api, ui):  # nobody listens any more
        with pytest.raises(ConnectionRefusedError), socket.create_connection(("127.0.0.1", port), timeout=2):
            pass


def test_serve_runs_the_api_alone_when_the_web_app_cannot_be_imported(tmp_path):
    code = (
        "import sys; sys.modules['web.app'] = None\n"  # makes `from web.app import launch` fail
        "from backend.serve import serve; serve(api_port=0, viser_port=0)"
    )
    server = _serve(tmp_path, code, warm=False)
    api = server.port(REST_URL)
    server.wait_for("Ctrl-C")
    assert "3D web app not available" in server.output
    assert httpx.get(f"http://127.0.0.1:{api}/api/health", timeout=5).status_code == 200
    code, _ = server.stop(timeout=30)
    assert code == 0


def test_serve_reports_a_port_in_use(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        server = _serve(tmp_path, f"from backend.serve import serve; serve(api_port={port}, web=False)", warm=False)
        server.wait_for("could not start")
        code = server.proc.wait(60)
    assert code != 0


def test_serve_stops_on_a_burst_of_signals(tmp_path):
    """Ctrl-C pressed twice, or a supervisor forwarding SIGTERM on top of its own: a handler
    interrupted by the next signal must not deadlock (Event.set in a handler did: the second
    handler waited for the lock the first one held, forever)."""
    server = _serve(tmp_path, "from backend.serve import serve; serve(api_port=0, web=False)", warm=False)
    server.wait_for("Ctrl-C")
    proc = server.proc
    deadline = time.monotonic() + 0.3  # signals as fast as they go
    while proc.poll() is None and time.monotonic() < deadline:
        proc.send_signal(signal.SIGTERM)
    code, out = server.stop(signal.SIGTERM, timeout=30)  # "serve hung after a burst of SIGTERM" otherwise
    assert code == 0 and "stopped" in out, out
