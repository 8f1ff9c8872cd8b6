"""Issue 16, stopping: a server stopped while it compiles kernels in the background (a first
start, empty kernel cache) stops cleanly — no segmentation fault at interpreter exit — and
says what it did with the compilation it was running."""

import os
import signal
import sys

import pytest

from tests._helpers import ServerProcess

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# one small system of one variant (the others unregistered): its default loops compile before the service
# is ready, the other loops after, in the background; the stop comes right then
SERVE_ONE_SYSTEM = (
    "from nmkane_core.run.registry import system_names, unregister\n"
    "[unregister(n) for n in system_names() if n != 'knife-edge']\n"
    "from backend.serve import serve\n"
    "serve(api_port=0, web=False)\n"
)
# what the server says it did with the background compilation (exactly one of them)
OUTCOMES = ("the other loops ready", "compilation was abandoned", "the other loops stopped with the service")


@pytest.mark.slow  # compiles in a kernel cache of its own, empty on purpose
def test_stop_during_background_compilation_on_an_empty_cache(tmp_path):
    env = {
        **os.environ,
        "NMKANE_DB": str(tmp_path / "runs.sqlite3"),
        "PYTHONUNBUFFERED": "1",
        "NMKANE_CACHE_DIR": str(tmp_path / "cache"),
        "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
        "PYTHONPATH": ROOT,
    }
    server = ServerProcess([sys.executable, "-c", SERVE_ONE_SYSTEM], env=env)
    server.wait_for("service is ready", timeout=900)
    # no fixed wait: the background warm-up starts as the line is printed and its first projected
    # loop compiles for seconds on an empty cache, while the stop below takes a fraction of one
    code, out = server.stop(signal.SIGTERM, timeout=30)  # within 30 s
    assert code == 0, f"exit status {code}:\n{out}"
    assert "nmkane: stopped" in out, out
    # The crash needed the interpreter to exit while a compilation ran (seen once, not every time):
    # the server must have finished compiling, or finished the step under way and stopped, or
    # abandoned it without a teardown — and say which.  (Before, a step that finished within the
    # stop's wait was said nowhere, and this test failed on a fast machine.)
    said = [o for o in OUTCOMES if o in out]
    assert len(said) == 1, out
