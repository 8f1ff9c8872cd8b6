"""Attack the REST service on loopback and print what it did, in one table (issue 44, item 10).

    .venv/bin/python scripts/attack.py [--quick] [--cache DIR]

Starts ``nmkane serve --no-web`` on free loopback ports with a store and a kernel cache in a
temporary folder (removed afterwards; ``--cache DIR``: a kernel cache of yours for the service
under attack, so it starts in seconds), and runs the long attacks in turn:

1. SIGTERM during the warm-up: a service on an empty kernel cache is sent SIGTERM once its log
   says the warm-up is under way (its first step done); the time to its exit and its status.
2. the 10⁷-point sweep: ``POST /api/sweeps`` with a grid of 10⁷ points (41 bytes); the wall
   time to its 422.
3. hostile requests: malformed JSON, huge bodies, headers and URLs, out-of-range, NaN and
   infinite values, unknown systems, huge ``t_final`` and ``every``, deep nesting, bad queries,
   methods and HTTP, then floods of concurrent connections; the answers by class, the 5xx, and
   whether ``/api/health`` and a run still answer afterwards.
4. slow readers: clients that GET a large run document or its CSV and read nothing, or a byte
   at a time; the service's resident memory before, at its peak and after they leave, and the
   other requests served meanwhile.
5. SIGKILL: runs and a sweep posted by concurrent clients, the service killed once half the runs
   are acknowledged (runs in flight), restarted on the same store: acknowledged runs found
   (byte-identical) vs lost.

Every wait is for a state (a log line, an answer, a count, the memory), polled with a deadline.
Exits 1 when a target is missed: a 5xx that is not one of the documented refusals (503 past the
256-connection cap or the run queue), ``/api/health`` or a run not answering afterwards, the 10⁷
sweep not refused with 422 within 1 s, SIGTERM not ending the warm-up with status 0 within 60 s,
the memory not back within 50 MiB of where it started, an acknowledged run or sweep lost.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path

import httpx

HERE = os.path.dirname(os.path.abspath(__file__))
if HERE not in sys.path:  # imported (tests/backend/test_attack_script.py): its helpers beside it, last
    sys.path.append(HERE)
from _attack_requests import GRID_10M, SMALL, burst, flood, hostile_requests  # noqa: E402
from _server import ROOT, rss_mib  # noqa: E402

if str(ROOT) not in sys.path:  # the tests' server process and coroutine runner (tests/_helpers.py)
    sys.path.append(str(ROOT))
from tests._helpers import REST_URL, ServerProcess, held_connections, non_reader, run_coroutine, until  # noqa: E402

RUN = {"system": "appell-hamel", "dt": 0.005, "t_final": 20}  # 4001 rows, the kill test's run
LIVE: list[subprocess.Popen] = []  # services started here, killed if the script fails


class Service(ServerProcess):
    """``nmkane serve --no-web`` on a free loopback port; its output read line by line in a thread
    (tests/_helpers.ServerProcess)."""

    def __init__(self, db: Path, cache: Path, extra_env: dict | None = None):
        env = {**os.environ, "NMKANE_DB": str(db), "NMKANE_CACHE_DIR": str(cache), "PYTHONUNBUFFERED": "1"}
        env = {**env, "PYTHONPATH": str(ROOT), **(extra_env or {})}
        cmd = [sys.executable, "-m", "nmkane_core.cli", "serve", "--no-web", "--api-port", "0"]
        super().__init__(cmd, env=env, cwd=ROOT)
        LIVE.append(self.proc)

    def ready(self, timeout: float = 600.0) -> str:
        """The REST base URL once the service serves (a cold kernel cache compiles first)."""
        port = self.port(REST_URL, timeout)
        self.wait_for("Ctrl-C", 60)
        return f"http://127.0.0.1:{port}"

    def end(self, sig: int, timeout: float = 120.0) -> tuple[int, float]:
        """Send ``sig`` and wait for the exit: (status, seconds from the signal to the exit)."""
        t0 = time.perf_counter()
        self.proc.send_signal(sig)
        try:
            code = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            code = self.proc.wait(10)
        seconds = time.perf_counter() - t0
        self._reader.join(10)
        return code, seconds


# ------------------------------------------------------------------ 1. SIGTERM during warm-up
def sigterm_during_warmup(db: Path, empty_cache: Path) -> dict:
    print("attack: SIGTERM during the warm-up of a service on an empty kernel cache", flush=True)
    svc = Service(db, empty_cache)
    svc.wait_for(r"nmkane: kernels \[1/", 600)  # the warm-up under way: its first step done
    code, seconds = svc.end(signal.SIGTERM)
    out = svc.output
    stopped = re.search(r"kernels stopped with the service after (\d+) of (\d+)", out)
    return {
        "code": code,
        "seconds": seconds,
        "during": stopped is not None and "the service is ready" not in out,
        "steps": f"{stopped.group(1)} of {stopped.group(2)}" if stopped else "?",
    }


# ------------------------------------------------------------------ 2. the 10⁷-point sweep
def sweep_10m(url: str, tries: int = 3) -> dict:
    print("attack: the 10⁷-point sweep", flush=True)
    codes, times = [], []
    with httpx.Client(base_url=url, timeout=120) as c:
        for _ in range(tries):
            t0 = time.perf_counter()
            r = c.post("/api/sweeps", json=GRID_10M)
            times.append(time.perf_counter() - t0)
            codes.append(r.status_code)
    return {"codes": codes, "times": times, "seconds": max(times), "body": len(json.dumps(GRID_10M))}


# ------------------------------------------------------------------ 3. hostile requests
def _idle(url: str) -> bool:
    """Whether the service answers its health check with no run in flight."""
    try:
        r = httpx.get(f"{url}/api/health", timeout=10)
    except httpx.HTTPError:
        return False
    return r.status_code == 200 and r.json()["runs_in_flight"] == 0


def hostile(url: str, pid: int, rounds: int, flood_n: int, floods: int) -> dict:
    port = int(url.rsplit(":", 1)[1])
    integrators = httpx.get(f"{url}/api/systems", timeout=60).json()["integrators"]
    from nmkane_core.integrate.methods import INTEGRATORS  # the kind of each (adaptive ones run long)

    each, once = hostile_requests({n: INTEGRATORS[n].kind for n in integrators if n in INTEGRATORS})
    print(
        f"attack: hostile requests, {len(each)} kinds × {rounds} rounds + {len(once)} once + {floods} floods",
        flush=True,
    )
    rss0, flooded = rss_mib(pid), Counter()
    t0 = time.perf_counter()
    seen = run_coroutine(burst(port, each * rounds + once, concurrency=32))
    for i in range(floods):
        flooded += run_coroutine(flood(port, flood_n))
        print(f"attack:   flood {i + 1}/{floods} of {flood_n} connections: {dict(flooded)}", flush=True)
    wall = time.perf_counter() - t0
    until(lambda: _idle(url), 120, 0.5)  # the runs the burst started have ended
    t1 = time.perf_counter()
    health = httpx.get(f"{url}/api/health", timeout=30)
    health_ms = (time.perf_counter() - t1) * 1e3
    run = httpx.post(f"{url}/api/runs", json=SMALL, timeout=60)
    return {
        "tried": sum(seen.values()) + sum(flooded.values()),
        "seen": seen + flooded,
        "burst": seen,
        "flood": (flooded, floods, flood_n),
        "wall": wall,
        "health": health.status_code,
        "health_ms": health_ms,
        "run": run.status_code,
        "rss": (rss0, rss_mib(pid)),
    }


# ------------------------------------------------------------------ 4. slow readers
BIG_RUN = {"system": "sliding-particle", "dt": 0.001, "t_final": 99.99, "every": 1}  # 100,000 rows, 20 MB


def _trickle(sock: socket.socket, stop: threading.Event, got: list[int]) -> None:
    """Read one byte every 50 ms until ``stop`` or the end of the connection."""
    sock.settimeout(0.05)
    while not stop.is_set():
        try:
            if not sock.recv(1):
                return
            got.append(1)
        except TimeoutError:
            continue
        except ConnectionResetError:
            return
        stop.wait(0.05)


def _probe(url: str, stop: threading.Event, seen: list[tuple[str, int, float]]) -> None:
    """What other clients get meanwhile: a health check and a small run, twice a second."""
    with httpx.Client(base_url=url, timeout=60) as c:
        while not stop.is_set():
            for what, call in (
                ("health", lambda: c.get("/api/health")),
                ("run", lambda: c.post("/api/runs", json=SMALL)),
            ):
                t0 = time.perf_counter()
                try:
                    code = call().status_code
                except httpx.HTTPError:
                    code = 0
                seen.append((what, code, time.perf_counter() - t0))
            stop.wait(0.5)


def slow_readers(url: str, pid: int, clients: tuple[int, int, int], deadline: float, big: dict) -> dict:
    """``clients``: how many read nothing of the document, of its CSV, and how many a byte at a time."""
    port, (silent, csv, trickle) = int(url.rsplit(":", 1)[1]), clients
    print(f"attack: slow readers: {silent} + {csv} (CSV) that read nothing, {trickle} a byte at a time", flush=True)
    posted = httpx.post(f"{url}/api/runs", json=big, timeout=300)
    assert posted.status_code == 201, posted.text[:300]
    run_id, size = posted.json()["id"], len(posted.content)
    del posted
    for path in (f"/api/runs/{run_id}", f"/api/runs/{run_id}.csv"):  # one-time costs of the code paths first
        assert httpx.get(f"{url}{path}", timeout=120).status_code == 200
    rss0 = rss_mib(pid)
    paths = [f"/api/runs/{run_id}"] * silent + [f"/api/runs/{run_id}.csv"] * csv + [f"/api/runs/{run_id}"] * trickle
    socks = [non_reader(port, p) for p in paths]
    t_open, ports = time.monotonic(), {s.getsockname()[1] for s in socks}
    stop, got, probes = threading.Event(), [[] for _ in range(trickle)], []
    threads = [
        threading.Thread(target=_trickle, args=(s, stop, g)) for s, g in zip(socks[silent + csv :], got, strict=True)
    ]
    threads.append(threading.Thread(target=_probe, args=(url, stop, probes)))
    for th in threads:
        th.start()
    peak = rss0  # until the service has dropped every slow connection (or a deadline well past its own),
    until(lambda: held_connections(port, ports) == len(socks), deadline)  # once it has taken them all
    while held_connections(port, ports) and time.monotonic() < t_open + deadline + 30:
        peak = max(peak, rss_mib(pid))
        time.sleep(0.05)
    last_drop, left = time.monotonic() - t_open, held_connections(port, ports)
    stop.set()
    for th in threads:
        th.join(60)
    for s in socks:
        s.close()
    back = until(lambda: rss_mib(pid) - rss0 < 50, 30, 0.5)  # the memory of the closed connections returns
    return {
        "clients": clients,
        "doc_mb": size / 1e6,
        "rss": (rss0, peak, rss_mib(pid)),
        "back": back,
        "dropped": (len(socks) - left, len(socks), last_drop),
        "trickled": sum(map(len, got)),
        "probes": probes,
    }


# ------------------------------------------------------------------ 5. SIGKILL durability
def _post_runs(url: str, tickets: list[int], acked: dict, sent: list[int], lock: threading.Lock) -> None:
    with httpx.Client(base_url=url, timeout=120) as c:
        while True:
            with lock:
                if not tickets:
                    return
                tickets.pop()
                sent[0] += 1
            try:
                r = c.post("/api/runs", json=RUN)
            except httpx.HTTPError:
                return  # the service is gone
            if r.status_code == 201:
                with lock:
                    acked[r.json()["id"]] = hashlib.sha256(r.content).hexdigest()


def sigkill(svc: Service, url: str, db: Path, cache: Path, runs: int, clients: int, env: dict) -> dict:
    print(f"attack: SIGKILL with runs in flight ({runs} runs by {clients} clients, and a sweep)", flush=True)
    sweep = {"settings": {"system": "sliding-particle", "t_final": 2}, "grid": ["gamma1=-30:-10:10000"]}
    r = httpx.post(f"{url}/api/sweeps", json=sweep, timeout=60)
    sweeps = [r.json()["id"]] if r.status_code == 202 else []
    acked: dict[str, str] = {}
    tickets, sent, lock = list(range(runs)), [0], threading.Lock()
    threads = [threading.Thread(target=_post_runs, args=(url, tickets, acked, sent, lock)) for _ in range(clients)]
    for th in threads:
        th.start()
    until(lambda: len(acked) >= runs // 2 or not any(t.is_alive() for t in threads), 600, 0.01)
    svc.proc.kill()  # SIGKILL, runs in flight
    svc.proc.wait(30)
    for th in threads:
        th.join(120)
    with lock:
        acked_now, in_flight = dict(acked), sent[0] - len(acked)
    again = Service(db, cache, env)
    url2 = again.ready()
    found = same = 0
    with httpx.Client(base_url=url2, timeout=120) as c:
        for run_id, digest in acked_now.items():
            got = c.get(f"/api/runs/{run_id}")
            found += got.status_code == 200
            same += got.status_code == 200 and hashlib.sha256(got.content).hexdigest() == digest
        states = [c.get(f"/api/sweeps/{i}") for i in sweeps]
        stored = c.get("/api/health").json()["runs_stored"]
    code, seconds = again.end(signal.SIGTERM)
    return {
        "acked": len(acked_now),
        "in_flight": in_flight,
        "found": found,
        "same": same,
        "sweeps": (len(sweeps), sum(s.status_code == 200 for s in states), [s.json().get("status") for s in states]),
        "stored": stored,
        "stop": (code, seconds),
    }


# ------------------------------------------------------------------ the whole attack
QUICK = dict(rounds=1, flood_n=40, floods=1, silent=6, csv=2, trickle=2, deadline=3.0, runs=16, clients=4)
FULL = dict(rounds=10, flood_n=300, floods=3, silent=40, csv=10, trickle=10, deadline=10.0, runs=200, clients=8)


def attack(tmp: Path, cache: Path | None, quick: bool) -> dict:
    """Every attack in turn; their figures."""
    n = QUICK if quick else FULL
    env = {"NMKANE_READ_TIMEOUT_S": str(n["deadline"])}
    main_cache = cache or tmp / "cache"
    out = {"mode": "quick" if quick else "full", "deadline": n["deadline"]}
    # on an empty cache: the service's own when it has none given (it starts on what is left)
    out["sigterm"] = sigterm_during_warmup(tmp / "warm.sqlite3", tmp / "cache" if cache is None else tmp / "empty")
    db = tmp / "runs.sqlite3"
    svc = Service(db, main_cache, env)
    url = svc.ready()
    out["sweep"] = sweep_10m(url)
    out["hostile"] = hostile(url, svc.proc.pid, n["rounds"], n["flood_n"], n["floods"])
    big = BIG_RUN if not quick else {**BIG_RUN, "t_final": 19.99}
    clients = (n["silent"], n["csv"], n["trickle"])
    out["slow"] = slow_readers(url, svc.proc.pid, clients, n["deadline"], big)
    out["kill"] = sigkill(svc, url, db, main_cache, n["runs"], n["clients"], env)
    return out


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:,.0f} ms" if seconds < 10 else f"{seconds:,.1f} s"


def verdicts(r: dict) -> dict[str, bool]:
    h, s, k, t = r["hostile"], r["slow"], r["kill"], r["sigterm"]
    return {
        "no 5xx server error": h["seen"]["5xx server error"] == 0,
        "health and a run answer after the burst": h["health"] == 200 and h["run"] == 201,
        "10⁷ sweep refused with 422 within 1 s": set(r["sweep"]["codes"]) == {422} and r["sweep"]["seconds"] < 1,
        "SIGTERM ends the warm-up, status 0, within 60 s": t["during"] and t["code"] == 0 and t["seconds"] < 60,
        "memory back within 50 MiB after the slow readers": s["back"],
        "other requests served during the slow readers": all(c in (200, 201) for _, c, _ in s["probes"]),
        "no acknowledged run or sweep lost": k["same"] == k["acked"] and k["sweeps"][1] == k["sweeps"][0],
    }


def table(r: dict) -> str:
    h, s, k, t, sw = r["hostile"], r["slow"], r["kill"], r["sigterm"], r["sweep"]
    seen = h["seen"]
    names = {"503 connection cap": "503 past the 256-connection cap", "503 queue full": "503 run queue full"}

    def classes(answers: Counter) -> str:
        return ", ".join(f"{n:,} {names.get(k, k)}" for k, n in sorted(answers.items()) if k != "5xx server error")

    flooded, floods, flood_n = h["flood"]
    probes = {w: [(c, d) for what, c, d in s["probes"] if what == w] for w in ("health", "run")}
    served = "; ".join(
        f"{w} {sum(c in (200, 201) for c, _ in p)}/{len(p)} answered, slowest {_ms(max((d for _, d in p), default=0))}"
        for w, p in probes.items()
    )
    silent, csv, trickle = s["clients"]
    rows = [
        ("hostile requests tried", f"{h['tried']:,} in {h['wall']:.0f} s"),
        ("their answers (a 503: a documented refusal)", f"burst: {classes(h['burst'])}; {floods} floods of "
         f"{flood_n} connections opened at once, then a request on each: {classes(flooded)}"),
        ("5xx (server errors)", f"**{seen['5xx server error']}**"),
        ("afterwards", f"`/api/health` {h['health']} in {_ms(h['health_ms'] / 1e3)}, a run {h['run']}; "
         f"RSS {h['rss'][0]:.0f} → {h['rss'][1]:.0f} MiB"),
        ("slow readers", f"{silent} read nothing of the {s['doc_mb']:.0f} MB document, {csv} nothing of its CSV, "
         f"{trickle} read a byte every 50 ms ({s['trickled']} bytes taken in all); read deadline {r['deadline']:g} s"),
        ("service memory (RSS) before → peak → after", "**{:.0f} → {:.0f} → {:.0f} MiB**".format(*s["rss"])),
        ("slow connections dropped by the service", f"{s['dropped'][0]} of {s['dropped'][1]}, the last "
         f"{s['dropped'][2]:.1f} s after they opened"),
        ("other requests meanwhile", served),
        ("10⁷-point sweep", f"**{'/'.join(map(str, sorted(set(sw['codes']))))} in "
         f"{' / '.join(_ms(x) for x in sw['times'])}** ({sw['body']}-byte body, {len(sw['times'])} tries)"),
        ("SIGTERM during the warm-up (empty cache)", f"**exit {t['code']} in {t['seconds']:.1f} s**, the warm-up "
         f"stopped after {t['steps']} steps"),
        ("SIGKILL with runs in flight", f"**{k['acked']} runs acknowledged, {k['found']} found "
         f"({k['same']} byte-identical), {k['acked'] - k['same']} lost**; {k['in_flight']} in flight not acknowledged"),
        ("the sweep killed with it", f"{k['sweeps'][1]} of {k['sweeps'][0]} found after the restart "
         f"({', '.join(map(str, k['sweeps'][2])) or '-'})"),
        ("the restarted service", f"{k['stored']:,} runs stored; SIGTERM: exit {k['stop'][0]} in {k['stop'][1]:.1f} s"),
    ]  # fmt: skip
    return "\n".join(["| attack | figure |", "|---|---|", *(f"| {a} | {b} |" for a, b in rows)])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="small counts and a 3 s read deadline (a smoke test)")
    ap.add_argument("--cache", type=Path, help="the kernel cache of the service under attack (default: a new one)")
    args = ap.parse_args(argv)
    tmp = Path(tempfile.mkdtemp(prefix="nmkane-attack-"))
    t0 = time.perf_counter()
    try:
        result = attack(tmp, args.cache, args.quick)
    finally:
        for proc in LIVE:
            if proc.poll() is None:
                proc.kill()
                proc.wait(10)
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\nattack: {result['mode']} mode, {time.perf_counter() - t0:.0f} s, {os.cpu_count()} CPU cores\n")
    print(table(result))
    checks = verdicts(result)
    print()
    for name, ok in checks.items():
        print(f"{'PASS' if ok else 'FAIL'}  {name}")
    return 0 if all(checks.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
