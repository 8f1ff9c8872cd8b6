"""Issue 16, stopping: a server stopped while it compiles kernels in the background (a first
start, empty kernel cache) stops cleanly — no segmentation fault at interpreter exit."""

import os
import signal
import subprocess
import sys
import time

import pytest

from tests._helpers import free_port

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.slow
def test_stop_during_background_compilation_on_an_empty_cache(tmp_path):
    api = free_port()
    env = {
        **os.environ,
        "NMKANE_DB": str(tmp_path / "runs.sqlite3"),
        "PYTHONUNBUFFERED": "1",
        "NMKANE_CACHE_DIR": str(tmp_path / "cache"),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
        "PYTHONPATH": ROOT,
    }
    proc = subprocess.Popen(
        [sys.executable, "-c", f"from backend.serve import serve; serve(api_port={api}, web=False)"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    lines, deadline = [], time.time() + 900
    while time.time() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        lines.append(line)
        if "service is ready" in line:
            break
    assert any("service is ready" in x for x in lines), "".join(lines)
    time.sleep(2.0)  # the background thread is compiling the first projected loop now
    assert not any("the other loops ready" in x for x in lines)
    t0 = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    out, _ = proc.communicate(timeout=120)
    took = time.monotonic() - t0
    assert proc.returncode == 0, f"exit status {proc.returncode}:\n{''.join(lines)}{out}"
    assert "stopped" in out and took < 30, (took, out)
    # The crash needed the interpreter to exit while a compilation ran (seen once, not every time):
    # the server must either have finished compiling or have abandoned it without a teardown.
    assert "the other loops ready" in out or "compilation was abandoned" in out, out
