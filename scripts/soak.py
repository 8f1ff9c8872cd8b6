"""Soak test of the REST service on loopback: steady mixed load for a bounded time.

    python scripts/soak.py [--minutes 10] [--clients 6]

Starts the service (fresh database, loopback, free port), then clients send a mix of good
runs, bad requests (422/413 expected) and singular starts (201 with status 'singular' or
switched) until the time is up. Reports requests served, answers by class, p99 latency
in the first and the last minute, the server's resident memory at the start and the
end, and stored runs vs acknowledged (201) runs.
"""

from __future__ import annotations

import argparse
import os
import random
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter

import httpx

GOOD = [
    {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 20},
    {"system": "appell-hamel", "model": "linear", "dt": 0.02, "t_final": 30, "gamma": -2},
    {"system": "sliding-particle", "gamma1": -20, "gamma2": -100, "dt": 0.01, "t_final": 50},
    {"system": "sliding-particle", "formulation": "minimal", "dt": 0.05, "t_final": 100},
    {"system": "sliding-particle", "projection": "blajer", "dt": 0.01, "t_final": 30},
]
SINGULAR = [
    {"system": "appell-hamel", "initial": {"u2": 0.0}, "t_final": 5},
    {"system": "appell-hamel", "initial": {"u2": 0.0}, "switching": False},
    {"system": "appell-hamel", "initial": {"u2": -1.5, "u1": 0.2}, "t_final": 10},
]
BAD = [
    {"system": "nope"},
    {"system": "appell-hamel", "dt": -1},
    {"system": "appell-hamel", "dt": "x"},
    {"system": "appell-hamel", "params": {"rho": -2}},
    {"system": "appell-hamel", "initial": {"u3": 1}},
    {"system": "appell-hamel", "dt": 1e-6, "t_final": 1000},
]
RAW_BAD = [b'{"system": "appell-hamel", "dt": NaN}', b"[" * 5000, b"{" + b" " * 70000 + b"}"]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _rss_mib(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--clients", type=int, default=6)
    args = ap.parse_args(argv)
    port = _free_port()
    tmp = tempfile.mkdtemp(prefix="nmkane-soak-")
    env = {**os.environ, "NMKANE_DB": os.path.join(tmp, "runs.sqlite3")}
    proc = subprocess.Popen(
        [sys.executable, "-m", "backend", "--port", str(port)],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    base = f"http://127.0.0.1:{port}"
    deadline = time.time() + 180
    while True:
        try:
            if httpx.get(f"{base}/api/health", timeout=1).status_code == 200:
                break
        except httpx.HTTPError:
            pass
        if time.time() > deadline or proc.poll() is not None:
            raise SystemExit("soak: the service did not start")
        time.sleep(0.2)
    rss_start = _rss_mib(proc.pid)
    start = time.perf_counter()
    end = start + args.minutes * 60
    lock = threading.Lock()
    answers: Counter = Counter()
    lat: list[tuple[float, float]] = []
    acked = [0]
    transport = Counter()

    def client(seed):
        rng = random.Random(seed)
        with httpx.Client(base_url=base, timeout=60) as c:
            while time.perf_counter() < end:
                kind = rng.choices(["good", "singular", "bad", "raw"], [0.6, 0.15, 0.2, 0.05])[0]
                t0 = time.perf_counter()
                try:
                    if kind == "raw":
                        r = c.post(
                            "/api/runs", content=rng.choice(RAW_BAD), headers={"content-type": "application/json"}
                        )
                    else:
                        body = rng.choice({"good": GOOD, "singular": SINGULAR, "bad": BAD}[kind])
                        r = c.post("/api/runs", json=body)
                    if rng.random() < 0.1:
                        c.get("/api/runs", params={"limit": 5})
                except httpx.HTTPError as e:
                    with lock:
                        transport[type(e).__name__] += 1
                    continue
                with lock:
                    answers[(kind, r.status_code)] += 1
                    lat.append((t0 - start, time.perf_counter() - t0))
                    if r.status_code == 201:
                        acked[0] += 1

    threads = [threading.Thread(target=client, args=(i,)) for i in range(args.clients)]
    for th in threads:
        th.start()
    rss_mid = []
    while any(th.is_alive() for th in threads):
        time.sleep(5)
        rss_mid.append(_rss_mib(proc.pid))
    for th in threads:
        th.join()
    wall = time.perf_counter() - start
    rss_end = _rss_mib(proc.pid)
    stored = httpx.get(f"{base}/api/health").json()["runs_stored"]
    proc.terminate()
    proc.wait(30)

    def p99(window):
        xs = sorted(d for t, d in lat if window[0] <= t < window[1])
        return xs[int(0.99 * (len(xs) - 1))] * 1e3 if xs else float("nan")

    total = sum(answers.values())
    print(f"soak: {wall / 60:.1f} min, {args.clients} clients, {total} requests ({total / wall:.1f}/s)")
    for (kind, code), n in sorted(answers.items()):
        print(f"  {kind:9s} -> {code}: {n}")
    print(f"  transport errors: {dict(transport) or 0}; 5xx: {sum(n for (k, c), n in answers.items() if c >= 500)}")
    print(f"p99 latency: first minute {p99((0, 60)):.0f} ms, last minute {p99((wall - 60, wall)):.0f} ms")
    print(f"server RSS: start {rss_start:.0f} MiB, max {max(rss_mid or [rss_end]):.0f} MiB, end {rss_end:.0f} MiB")
    print(f"stored runs {stored} == acknowledged {acked[0]}: {stored == acked[0]}")
    ok = stored == acked[0] and not transport and all(c < 500 for (k, c) in answers)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
