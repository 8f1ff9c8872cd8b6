"""Load test of the REST service on loopback, bounded in time and count.

    .venv/bin/python scripts/load_test.py [--clients 16] [--seconds 30] [--max-requests 20000]
                                          [--url http://127.0.0.1:8000]

Without --url it starts the service (``python -m backend``) on a free loopback port with a
fresh database in a temporary directory (removed afterwards).  N clients (threads, one
keep-alive httpx connection each) post the small run — Appell–Hamel, nonlinear, 20 s at
Δt = 0.01, 2001 rows × 10 states — back to back for the given time, and read each whole
answer.  It prints runs/s, latency percentiles, answers by status, transport errors, and
the stored runs against the 201 answers (every acknowledged id is then fetched back), and
exits 0 only if the targets of issue 4 are met: ≥ 100 runs/s, p99 ≤ 250 ms, no errors,
stored == acknowledged.
"""

from __future__ import annotations

import argparse
import ipaddress
import os
import shutil
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from urllib.parse import urlparse

import httpx

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 20}
TARGET_RATE, TARGET_P99_MS = 100.0, 250.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _loopback(url: str) -> bool:
    host = urlparse(url).hostname or ""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def _cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a process (Linux /proc), or None."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def _start_service(db: str) -> tuple[subprocess.Popen, str]:
    port = _free_port()
    root = Path(__file__).resolve().parents[1]
    proc = subprocess.Popen(
        [sys.executable, "-m", "backend", "--port", str(port), "--db", db],
        cwd=root,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    deadline = time.time() + 600  # a cold kernel cache compiles first
    while True:
        try:
            if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                return proc, base
        except httpx.HTTPError:
            pass
        if proc.poll() is not None or time.time() > deadline:
            proc.kill()
            raise SystemExit("load_test: the service did not start")
        time.sleep(0.2)


def _pct(sorted_values: list[float], p: float) -> float:
    """Nearest-rank percentile (ms)."""
    if not sorted_values:
        return float("nan")
    k = max(0, min(len(sorted_values) - 1, int(-(-p * len(sorted_values) // 1)) - 1))
    return sorted_values[k] * 1e3


class Record:
    """What REST clients saw, shared between threads: latencies (s), answers by status,
    transport errors by kind, acknowledged run ids; ``lock`` guards them."""

    def __init__(self, latencies=None, codes=None, errors=None, acked=None, lock=None):
        self.latencies: list[float] = [] if latencies is None else latencies
        self.codes: Counter = Counter() if codes is None else codes
        self.errors: Counter = Counter() if errors is None else errors
        self.acked: list[str] = [] if acked is None else acked
        self.lock = threading.Lock() if lock is None else lock


def post_runs(base: str, keep_going, record: Record, body: dict = SMALL) -> None:
    """One client: post ``body`` to ``base``/api/runs back to back on one keep-alive
    connection while ``keep_going()`` says so, reading each whole answer into ``record``."""
    with httpx.Client(base_url=base, timeout=30) as c:
        while keep_going():
            t0 = time.perf_counter()
            try:
                r = c.post("/api/runs", json=body)
                content = r.content  # the whole document is read
            except httpx.HTTPError as e:
                with record.lock:
                    record.errors[type(e).__name__] += 1
                continue
            dt = time.perf_counter() - t0
            # the id from Location: parsing 570 kB of JSON here would load the shared CPUs
            run_id = (
                r.headers.get("location", "").rsplit("/", 1)[-1] or None
                if r.status_code == 201 and len(content) > 100_000
                else None
            )
            with record.lock:
                record.codes[r.status_code] += 1
                record.latencies.append(dt)
                if run_id:
                    record.acked.append(run_id)
                elif r.status_code == 201:
                    record.errors["short 201 body"] += 1


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clients", type=int, default=16, help="concurrent clients (1..64)")
    ap.add_argument("--seconds", type=float, default=30.0, help="duration (at most 300 s)")
    ap.add_argument("--max-requests", type=int, default=20_000, help="stop after this many requests")
    ap.add_argument("--url", help="an already running service (loopback only)")
    args = ap.parse_args(argv)
    if not 1 <= args.clients <= 64 or not 0 < args.seconds <= 300 or args.max_requests < 1:
        ap.error("bounds: 1 ≤ clients ≤ 64, 0 < seconds ≤ 300, max-requests ≥ 1")

    proc, tmp = None, None
    if args.url:
        if not _loopback(args.url):
            raise SystemExit("load_test: only loopback targets are allowed")
        base = args.url.rstrip("/")
    else:
        tmp = tempfile.mkdtemp(prefix="nmkane-load-")
        proc, base = _start_service(os.path.join(tmp, "runs.sqlite3"))
    try:
        return _run(args, base, proc)
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait(60)
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)


def _run(args, base: str, proc: subprocess.Popen | None) -> int:
    stored_before = httpx.get(f"{base}/api/health").json()["runs_stored"]
    latencies: list[float] = []
    codes: Counter = Counter()
    errors: Counter = Counter()
    acked: list[str] = []
    lock = threading.Lock()
    sent = [0]
    start_gate = threading.Barrier(args.clients + 1)
    stop_at = [0.0]

    def client():
        start_gate.wait()

        def keep_going() -> bool:
            with lock:
                if time.perf_counter() >= stop_at[0] or sent[0] >= args.max_requests:
                    return False
                sent[0] += 1
                return True

        post_runs(base, keep_going, Record(latencies, codes, errors, acked, lock))

    threads = [threading.Thread(target=client, daemon=True) for _ in range(args.clients)]
    for th in threads:
        th.start()
    cpu0 = _cpu_seconds(proc.pid) if proc else None
    cpu_self0 = time.process_time()
    stop_at[0] = time.perf_counter() + args.seconds
    t0 = time.perf_counter()
    start_gate.wait()
    for th in threads:
        th.join()
    wall = time.perf_counter() - t0
    cpu1 = _cpu_seconds(proc.pid) if proc else None
    cpu_self = time.process_time() - cpu_self0

    stored = httpx.get(f"{base}/api/health").json()["runs_stored"] - stored_before
    missing = 0
    with httpx.Client(base_url=base, timeout=30) as c:  # after the timed window
        for run_id in acked:
            if c.get(f"/api/runs/{run_id}").status_code != 200:
                missing += 1
    created = codes.get(201, 0)
    latencies.sort()
    rate = created / wall
    p50, p90, p99, worst = (_pct(latencies, p) for p in (0.50, 0.90, 0.99, 1.0))
    non_201 = sum(n for code, n in codes.items() if code != 201)

    print(
        f"target   {base}  ({args.clients} clients, {wall:.1f} s, {sum(codes.values())} requests, "
        f"{os.cpu_count()} CPU cores)"
    )
    print(f"rate     {rate:.1f} runs/s acknowledged (201)")
    print(f"latency  p50 {p50:.1f} ms  p90 {p90:.1f} ms  p99 {p99:.1f} ms  max {worst:.1f} ms")
    print(f"answers  {dict(sorted(codes.items()))}  transport errors: {dict(errors) or 0}")
    print(
        f"stored   {stored} new runs in the database for {created} answers 201 "
        f"({'equal' if stored == created else 'NOT EQUAL'}); acknowledged ids not found: {missing}"
    )
    if cpu0 is not None and cpu1 is not None:
        print(f"cpu      server {(cpu1 - cpu0) / wall:.2f} cores, load clients {cpu_self / wall:.2f} cores")
    ok = (
        rate >= TARGET_RATE
        and p99 <= TARGET_P99_MS
        and not errors
        and non_201 == 0
        and stored == created
        and missing == 0
    )
    print(
        f"result   {'PASS' if ok else 'FAIL'} (targets: ≥ {TARGET_RATE:g} runs/s, p99 ≤ {TARGET_P99_MS:g} ms, "
        "no errors, stored == acknowledged)"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
