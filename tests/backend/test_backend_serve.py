"""``serve()``: the REST API and the 3D web app side by side, both stopped by SIGTERM/Ctrl-C."""

import os
import re
import signal
import socket
import subprocess
import sys
import time

import httpx
import pytest

from tests._helpers import free_port


def _serve(tmp_path, code):
    env = {**os.environ, "NMKANE_DB": str(tmp_path / "runs.sqlite3"), "PYTHONUNBUFFERED": "1"}
    return subprocess.Popen(
        [sys.executable, "-c", code], env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
    )


def _read_until(proc, pattern, timeout=600):  # a cold kernel cache compiles first
    lines, deadline = [], time.time() + timeout
    while time.time() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if re.search(pattern, line):
            return "".join(lines)
    proc.kill()
    pytest.fail("no line matching {!r} in:\n{}".format(pattern, "".join(lines)))


def _stop(proc, sig=signal.SIGTERM):
    proc.send_signal(sig)
    out, _ = proc.communicate(timeout=30)
    return proc.returncode, out


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_serve_starts_api_and_web_app_and_stops_both(tmp_path, sig):
    api, ui = free_port(), free_port()
    proc = _serve(tmp_path, f"from backend.serve import serve; serve(api_port={api}, viser_port={ui})")
    out = _read_until(proc, "Ctrl-C")
    assert f"http://127.0.0.1:{api}/api" in out and f"http://127.0.0.1:{api}/docs" in out
    assert f"http://127.0.0.1:{ui}/" in out
    assert httpx.get(f"http://127.0.0.1:{api}/api/health", timeout=5).json()["status"] == "ok"
    assert httpx.get(f"http://127.0.0.1:{ui}/", timeout=5).status_code == 200
    code, rest = _stop(proc, sig)
    assert code == 0 and "stopped" in rest, rest
    for port in (api, ui):  # nobody listens any more
        with pytest.raises(ConnectionRefusedError), socket.create_connection(("127.0.0.1", port), timeout=2):
            pass


def test_serve_runs_the_api_alone_when_the_web_app_cannot_be_imported(tmp_path):
    api = free_port()
    code = (
        "import sys; sys.modules['web.app'] = None\n"  # makes `from web.app import launch` fail
        f"from backend.serve import serve; serve(api_port={api}, viser_port=0)"
    )
    proc = _serve(tmp_path, code)
    out = _read_until(proc, "Ctrl-C")
    assert "3D web app not available" in out
    assert httpx.get(f"http://127.0.0.1:{api}/api/health", timeout=5).status_code == 200
    code, _ = _stop(proc)
    assert code == 0


def test_serve_reports_a_port_in_use(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = _serve(tmp_path, f"from backend.serve import serve; serve(api_port={port}, web=False)")
        out, _ = proc.communicate(timeout=600)
    assert proc.returncode != 0 and "could not start" in out


def test_serve_stops_on_a_burst_of_signals(tmp_path):
    """Ctrl-C pressed twice, or a supervisor forwarding SIGTERM on top of its own: a handler
    interrupted by the next signal must not deadlock (Event.set in a handler did: the second
    handler waited for the lock the first one held, forever)."""
    api, ui = free_port(), free_port()
    proc = _serve(tmp_path, f"from backend.serve import serve; serve(api_port={api}, viser_port={ui}, web=False)")
    _read_until(proc, "Ctrl-C")
    deadline = time.time() + 0.3  # signals as fast as they go
    while proc.poll() is None and time.time() < deadline:
        proc.send_signal(signal.SIGTERM)
    try:
        out, _ = proc.communicate(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("serve hung after a burst of SIGTERM")
    assert proc.returncode == 0 and "stopped" in out, out
