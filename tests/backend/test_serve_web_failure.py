"""A web app that cannot start makes ``nmkane serve`` end non-zero with the reason on one line
(issue 44): with ``NMKANE_MAX_SESSIONS=x`` the web app's child fails, and the stop that follows
ended the process through ``os._exit(0)`` while a background warm-up still compiled — exit 0,
the reason lost."""

import os
import subprocess
import sys


def test_a_web_app_that_cannot_start_ends_serve_non_zero_with_its_reason(tmp_path):
    env = {**os.environ, "NMKANE_MAX_SESSIONS": "x", "NMKANE_DATA_DIR": str(tmp_path)}
    cmd = [sys.executable, "-m", "nmkane_core.cli", "serve", "--api-port", "0", "--viser-port", "0"]
    out = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=600, stdin=subprocess.DEVNULL)
    assert out.returncode != 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert "Traceback" not in out.stderr, out.stderr[-3000:]
    reason = [line for line in out.stderr.splitlines() if "nmkane serve: error:" in line]
    assert len(reason) == 1 and "web app" in reason[0] and "NMKANE_MAX_SESSIONS" in reason[0], out.stderr[-3000:]
