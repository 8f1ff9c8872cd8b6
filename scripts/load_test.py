"""Load test of the REST service on loopback (bounded in time and count).

    python scripts/load_test.py [--clients 16] [--seconds 30] [--max-requests 20000]

Starts the service on a free loopback port with a fresh database (or uses --url, which
must be a loopback address), then N clients post the small run (Appell–Hamel, nonlinear,
20 s at Δt = 0.01) for the given time. Prints runs/s, latency percentiles, errors by
class, and stored runs vs 201 answers.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from urllib.parse import urlparse

import httpx

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 20}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--clients", type=int, default=16)
    ap.add_argument("--seconds", type=float, default=30.0)
    ap.add_argument("--max-requests", type=int, default=20_000)
    ap.add_argument("--url", help="an already running service (loopback only)")
    args = ap.parse_args(argv)

    proc = None
    if args.url:
        host = urlparse(args.url).hostname
        if host not in ("127.0.0.1", "localhost", "::1"):
            raise SystemExit("load_test: only loopback targets are allowed")
        base = args.url.rstrip("/")
    else:
        port = _free_port()
        tmp = tempfile.mkdtemp(prefix="nmkane-load-")
        env = {**os.environ, "NMKANE_DB": os.path.join(tmp, "runs.sqlite3")}
        proc = subprocess.Popen([sys.executable, "-m", "backend", "--port", str(port)], env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        base = f"http://127.0.0.1:{port}"
        deadline = time.time() + 120
        while True:
            try:
                if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                    break
            except httpx.HTTPError:
                pass
            if time.time() > deadline:
                proc.kill()
                raise SystemExit("load_test: the service did not start")
            time.sleep(0.2)

    stored_before = httpx.get(f"{base}/api/health").json()["runs_stored"]
    lat, codes, errors = [], Counter(), Counter()
    lock = threading.Lock()
    sent = [0]
    stop_at = time.perf_counter() + args.seconds

    def client():
        with httpx.Client(base_url=base, timeout=30) as c:
            while time.perf_counter() < stop_at:
                with lock:
                    if sent[0] >= args.max_requests:
                        return
                    sent[0] += 1
                t0 = time.perf_counter()
                try:
                    r = c.post("/api/runs", json=SMALL)
                    # read the whole document, as a real client would
                    ok = r.status_code == 201 and len(r.content) > 100_000
                except httpx.HTTPError as e:
                    with lock:
                        errors[type(e).__name__] += 1
                    continue
                dt = time.perf_counter() - t0
                with lock:
                    codes[r.status_code] += 1
                    if ok:
                        lat.append(dt)
                    elif r.status_code == 201:
                        errors["short body"] += 1

    t0 = time.perf_counter()
    threads = [threading.Thread(target=client) for _ in range(args.clients)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    wall = time.perf_counter() - t0
    stored = httpx.get(f"{base}/api/health").json()["runs_stored"] - stored_before
    created = codes.get(201, 0)
    lat.sort()

    def pct(p):
        return lat[min(len(lat) - 1, int(p * len(lat)))] * 1e3 if lat else float("nan")

    print(f"clients {args.clients}, {wall:.1f} s, {sum(codes.values())} requests")
    print(f"201 created: {created}  ({created / wall:.1f} runs/s sustained)")
    print(f"latency ms: p50 {pct(0.50):.1f}  p90 {pct(0.90):.1f}  p99 {pct(0.99):.1f}  max {pct(1.0):.1f}"
          f"  mean {statistics.fmean(lat) * 1e3 if lat else float('nan'):.1f}")
    print(f"status codes: {dict(codes)}  transport errors: {dict(errors) or 0}")
    print(f"stored runs: {stored}  == 201 answers: {stored == created}")
    if proc is not None:
        proc.terminate()
        proc.wait(30)
    return 0 if stored == created and not errors and set(codes) == {201} else 1


if __name__ == "__main__":
    sys.exit(main())
