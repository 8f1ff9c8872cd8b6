"""Stopping a first start: SIGTERM while ``nmkane serve`` prepares the systems' models (empty
kernel cache, before the API answers) ends the warm-up after the step under way and stops
cleanly, saying so (issue 44, item 6: it was ignored until the warm-up had finished)."""

import os
import signal
import sys

import pytest

from tests._helpers import ServerProcess

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SERVE = "from backend.serve import serve\nserve(api_port=0, web=False)\n"


@pytest.mark.slow  # derives in a kernel cache of its own, empty on purpose
def test_sigterm_during_the_first_start_warm_up_stops_it_after_the_step_under_way(tmp_path):
    env = {
        **os.environ,
        "NMKANE_DB": str(tmp_path / "runs.sqlite3"),
        "PYTHONUNBUFFERED": "1",
        "NMKANE_CACHE_DIR": str(tmp_path / "cache"),
        "PYTHONPATH": ROOT,
    }
    server = ServerProcess([sys.executable, "-c", SERVE], env=env)
    server.wait_for(r"nmkane: kernels \[1/", timeout=300)  # the warm-up is under way: the first step done
    code, out = server.stop(signal.SIGTERM, timeout=120)
    assert code == 0, f"exit status {code}:\n{out}"
    assert "kernels stopped with the service after" in out and "nmkane: stopped" in out, out
    assert "the service is ready" not in out and "REST API" not in out, out
