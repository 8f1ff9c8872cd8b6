"""Helpers of the load scripts: start ``nmkane serve`` on free loopback ports, read a process
tree's CPU time and resident memory from /proc (Linux)."""

from __future__ import annotations

import contextlib
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import httpx

ROOT = Path(__file__).resolve().parents[1]


def tree_pids(pid: int) -> list[int]:
    """``pid`` and its descendants (Linux /proc; the web app may run in a child process)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            with contextlib.suppress(OSError, ValueError):
                todo += [int(c) for c in (task / "children").read_text().split()]
    return out


def cpu_seconds(pid: int) -> float:
    """User + system CPU seconds of ``pid`` and its descendants."""
    total = 0.0
    for p in tree_pids(pid):
        try:
            fields = Path(f"/proc/{p}/stat").read_text().rsplit(")", 1)[1].split()
            total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, ValueError, IndexError):
            pass
    return total


def rss_mib(pid: int) -> float:
    """Resident memory (MiB) of ``pid`` and its descendants."""
    total = 0.0
    for p in tree_pids(pid):
        try:
            for line in Path(f"/proc/{p}/status").read_text().splitlines():
                if line.startswith("VmRSS:"):
                    total += int(line.split()[1]) / 1024
        except (OSError, ValueError):
            pass
    return total


def start_serve(db: str, max_sessions: int = 40, timeout_s: float = 600.0) -> tuple[subprocess.Popen, str, int]:
    """``nmkane serve`` on free loopback ports with the store ``db``; returns the process, the
    REST base URL and the web app's port once both answer (a cold kernel cache compiles first)."""
    env = {**os.environ, "NMKANE_DB": db, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "nmkane_core.cli",
            "serve",
            "--api-port",
            "0",
            "--viser-port",
            "0",
            "--max-sessions",
            str(max_sessions),
        ],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    found: dict[str, str] = {}

    def read():
        assert proc.stdout is not None
        for line in proc.stdout:
            m = re.search(r"REST API\s+(http://\S+)/api", line)
            if m:
                found["api"] = m.group(1)
            m = re.search(r"3D web app\s+http://[^:/]+:(\d+)/", line)
            if m:
                found["web"] = m.group(1)

    threading.Thread(target=read, daemon=True).start()
    deadline = time.time() + timeout_s
    while not ("api" in found and "web" in found):
        if proc.poll() is not None or time.time() > deadline:
            proc.kill()
            raise SystemExit("the service did not start (nmkane serve)")
        time.sleep(0.2)
    while True:
        try:
            if httpx.get(f"{found['api']}/api/health", timeout=2).status_code == 200:
                break
        except httpx.HTTPError:
            pass
        if time.time() > deadline:
            proc.kill()
            raise SystemExit("the service did not answer /api/health")
        time.sleep(0.2)
    return proc, found["api"], int(found["web"])


def stop_serve(proc: subprocess.Popen, timeout_s: float = 60.0) -> int | None:
    """SIGTERM, then wait (SIGKILL after ``timeout_s``); returns the exit status."""
    proc.terminate()
    try:
        return proc.wait(timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.wait(10)
