"""Soak test of the service on loopback: steady mixed load for a bounded time.

    python scripts/soak.py [--minutes 10] [--clients 6] [--web-sessions 0]

Starts the service (fresh database, loopback, free ports), then clients send a mix of good
runs, bad requests (422/413 expected) and singular starts (201 with status 'singular' or
switched) until the time is up.  With ``--web-sessions N`` the service runs with its 3D
web app (``nmkane serve``) and N headless viser clients (``scripts/viser_client.py``)
connect, watch for 10–90 s, leave and come back, so sessions open and close throughout.
Reports requests served, answers by class, p99 latency in the first and the last minute,
the server's resident memory (start, peak, end; the web app's child process included),
stored runs vs acknowledged (201) runs, and acknowledged ids not found afterwards.
"""

from __future__ import annotations

import argparse
import asyncio
import atexit
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

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _server import rss_mib, start_serve, stop_serve

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


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--clients", type=int, default=6)
    ap.add_argument("--web-sessions", type=int, default=0, help="headless web clients coming and going (0: REST only)")
    args = ap.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="nmkane-soak-")
    db = os.path.join(tmp, "runs.sqlite3")
    web = None
    if args.web_sessions > 0:
        proc, base, web_port = start_serve(db, max_sessions=max(40, args.web_sessions))
        web = _web_load(web_port, args.web_sessions, args.minutes * 60)
    else:
        port = _free_port()
        env = {**os.environ, "NMKANE_DB": db}
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
    atexit.register(lambda: proc.poll() is None and proc.kill())  # a soak that fails leaves no server
    rss_start = rss_mib(proc.pid)
    start = time.perf_counter()
    end = start + args.minutes * 60
    lock = threading.Lock()
    answers: Counter = Counter()
    lat: list[tuple[float, float]] = []
    acked: list[str] = []
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
                        acked.append(r.headers.get("location", "").rsplit("/", 1)[-1])

    threads = [threading.Thread(target=client, args=(i,)) for i in range(args.clients)]
    for th in threads:
        th.start()
    rss_mid = []
    last_line = time.perf_counter()
    print(f"soak: started, server RSS {rss_start:.0f} MiB", flush=True)
    while any(th.is_alive() for th in threads):
        time.sleep(5)
        rss_mid.append(rss_mib(proc.pid))
        if time.perf_counter() - last_line >= 60:  # progress, so a cut-short soak still says something
            last_line = time.perf_counter()
            with lock:
                n5 = sum(n for (k, c), n in answers.items() if _failed(c))
                full = sum(n for (k, c), n in answers.items() if c == STORE_FULL)
                line = (
                    f"{len(acked)} acknowledged, {sum(answers.values())} answers, {n5} 5xx, "
                    f"{full} refused (store full), {dict(transport) or 0}"
                )
            extra = f", web sessions so far {web.report['sessions']}" if web is not None else ""
            print(f"soak: {(last_line - start) / 60:.0f} min: {line}; RSS {rss_mid[-1]:.0f} MiB{extra}", flush=True)
    for th in threads:
        th.join()
    wall = time.perf_counter() - start
    web_report = web.join() if web is not None else None
    time.sleep(5)  # closed sessions' memory is returned a little later
    rss_end = rss_mib(proc.pid)
    stored = httpx.get(f"{base}/api/health", timeout=120).json()["runs_stored"]
    with httpx.Client(base_url=base, timeout=60) as c:
        lost = [i for i in acked if not i or c.head(f"/api/runs/{i}", timeout=120).status_code != 200]
    status = stop_serve(proc) if web is not None else (proc.terminate(), proc.wait(30))[1]

    def p99(window):
        xs = sorted(d for t, d in lat if window[0] <= t < window[1])
        return xs[int(0.99 * (len(xs) - 1))] * 1e3 if xs else float("nan")

    total = sum(answers.values())
    print(f"soak: {wall / 60:.1f} min, {args.clients} clients, {total} requests ({total / wall:.1f}/s)")
    for (kind, code), n in sorted(answers.items()):
        print(f"  {kind:9s} -> {code}: {n}")
    n5 = sum(n for (k, c), n in answers.items() if _failed(c))
    print(f"  transport errors: {dict(transport) or 0}; 5xx other than 507 (store full, by policy): {n5}")
    print(f"p99 latency: first minute {p99((0, 60)):.0f} ms, last minute {p99((wall - 60, wall)):.0f} ms")
    print(f"server RSS: start {rss_start:.0f} MiB, max {max(rss_mid or [rss_end]):.0f} MiB, end {rss_end:.0f} MiB")
    print(f"stored runs {stored} == acknowledged {len(acked)}: {stored == len(acked)}")
    print(f"acknowledged ids not found afterwards: {len(lost)}")
    web_ok = True
    if web_report is not None:
        print(
            f"web: {web_report['sessions']} sessions opened and closed, {web_report['errors']} failed "
            f"({web_report['first_errors']}), {web_report['frames']} frames received"
        )
        web_ok = web_report["errors"] == 0 and web_report["sessions"] > 0
    print(f"server stopped with status {status}")
    ok = stored == len(acked) and not lost and not transport and not any(_failed(c) for (k, c) in answers) and web_ok
    return 0 if ok else 1


STORE_FULL = 507  # the store's cap reached: refused by the service's stated policy, nothing lost


def _failed(code: int) -> bool:
    """A server error; 507 is the store cap doing its job (the acknowledged runs are all checked)."""
    return code >= 500 and code != STORE_FULL


class _WebLoad:
    """Headless viser clients (an asyncio loop in a thread): each connects, watches 10–90 s,
    leaves, and comes back, until the time is up."""

    def __init__(self, port: int, n: int, seconds: float):
        self.report = {"sessions": 0, "errors": 0, "first_errors": [], "frames": 0}
        self.thread = threading.Thread(target=lambda: asyncio.run(self._main(port, n, seconds)), daemon=True)
        self.thread.start()

    async def _main(self, port: int, n: int, seconds: float) -> None:
        import viser
        from viser_client import ClientStats, run_client

        end = time.monotonic() + seconds

        async def student(i: int) -> None:
            rng = random.Random(1000 + i)
            await asyncio.sleep(rng.uniform(0, 10))
            while time.monotonic() < end - 5:
                stats = ClientStats(i)
                stay = min(rng.uniform(10, 90), end - time.monotonic())
                await run_client(f"ws://127.0.0.1:{port}/", viser.__version__, time.monotonic() + stay, stats)
                self.report["sessions"] += 1
                self.report["frames"] += len(stats.frames)
                if stats.error or not stats.frames:
                    self.report["errors"] += 1
                    if len(self.report["first_errors"]) < 3:
                        self.report["first_errors"].append(stats.error or "no frame received")
                await asyncio.sleep(rng.uniform(0.5, 5))

        await asyncio.gather(*(student(i) for i in range(n)))

    def join(self) -> dict:
        self.thread.join()
        return self.report


def _web_load(port: int, n: int, seconds: float) -> _WebLoad:
    return _WebLoad(port, n, seconds)


if __name__ == "__main__":
    sys.exit(main())
