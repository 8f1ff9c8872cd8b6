"""Classroom capacity: many browsers animating while REST clients post runs, on loopback.

    .venv/bin/python scripts/classroom.py --sessions 30 --rest-clients 4 --seconds 60 [--browsers 2]

Starts ``nmkane serve`` (fresh store, loopback, free ports), then, bounded in time:

1. REST alone for ``--baseline-seconds``: K clients post the small run back to back
   (``scripts/load_test.py``'s client) — the latency without web load;
2. N headless viser clients (``scripts/viser_client.py``: viser 1.1's websocket protocol,
   in a process of their own) connect and wait until every one receives frames;
   then ``--web-only-seconds`` of web load alone: the server's CPU per session;
3. for ``--seconds``: the N clients, M headless Chromium pages (Playwright; they count
   the frames in which the mechanism moved on the page, a realism check) and the K REST
   clients together.

It prints frames per second per client (min / median / max over the window of step 3),
the browsers' frames per second, REST p50/p99 alone and under web load, the server's CPU
(the API process and the web app's process) and resident memory, and exits 1 when a
target is missed: every websocket client ≥ ``--min-fps`` (20), REST p99 ≤ ``--max-p99-ms``
(250), no error, no refused connection.
"""

from __future__ import annotations

import argparse
import asyncio
import multiprocessing
import os
import shutil
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from _server import cpu_seconds, rss_mib, start_serve, stop_serve, tree_pids  # noqa: E402
from load_test import Record, _pct, post_runs  # noqa: E402

BODY_MOVES = """() => {
  window.__frames = []; let last = null;
  const step = () => {
    const nodes = window.__viserMutable ? window.__viserMutable.nodeRefFromName : {};
    let key = '';
    for (const name in nodes) {
      const n = nodes[name];
      if (n && n.position) key += n.position.toArray().join(',') + n.quaternion.toArray().join(',');
    }
    if (key !== last) { window.__frames.push(performance.now() / 1000); last = key; }
    requestAnimationFrame(step);
  };
  requestAnimationFrame(step);
}"""


def _ws_worker(port: int, n: int, seconds: float, ready, stop, out) -> None:
    """Child process: ``n`` viser clients for at most ``seconds``, until ``stop`` is set (the
    measured window is over); sets ``ready`` once every one has received frames (or failed),
    then puts their stats on ``out``."""
    import viser
    from viser_client import ClientStats, run_client

    async def main() -> list[ClientStats]:
        stop_at = time.monotonic() + seconds
        stats = [ClientStats(i) for i in range(n)]
        tasks = []
        for s in stats:
            tasks.append(asyncio.create_task(run_client(f"ws://127.0.0.1:{port}/", viser.__version__, stop_at, s)))
            await asyncio.sleep(0.05)
        while not all(len(s.frames) >= 10 or s.error for s in stats) and time.monotonic() < stop_at:
            await asyncio.sleep(0.2)
        ready.set()
        clients = asyncio.gather(*tasks)
        told = asyncio.ensure_future(asyncio.to_thread(stop.wait, max(0.0, stop_at - time.monotonic())))
        await asyncio.wait([clients, told], return_when=asyncio.FIRST_COMPLETED)
        for task in tasks:  # told to stop: the clients leave now (what they counted is kept)
            task.cancel()
        await asyncio.gather(clients, told, return_exceptions=True)
        return stats

    stats = asyncio.run(main())
    out.put([(s.frames, s.error, s.windows, s.bytes) for s in stats])


def _browser_worker(port: int, m: int, start_at: float, seconds: float, out) -> None:
    """Child process: ``m`` Chromium pages; the frames per second each showed a node move
    between the monotonic times start_at and start_at + seconds (or an error)."""
    try:
        from playwright.sync_api import sync_playwright

        sys.path.insert(0, str(HERE.parent))
        from web.screenshot import CHROMIUM_ARGS, chromium_path, open_page

        exe = chromium_path()
        if exe is None:
            out.put(("skipped", "headless Chromium not installed"))
            return
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path=exe, headless=True, args=CHROMIUM_ARGS)
            pages = [open_page(browser, f"http://127.0.0.1:{port}/?hideViserLogo", 900, 600, 180000) for _ in range(m)]
            time.sleep(max(0.0, start_at - time.monotonic()))
            for page in pages:
                page.evaluate(BODY_MOVES)
            t0 = time.monotonic()
            time.sleep(max(5.0, start_at + seconds - time.monotonic()))  # pages may load slowly
            fps = []
            for page in pages:
                frames = page.evaluate("window.__frames.length")
                fps.append(frames / (time.monotonic() - t0))
            browser.close()
        out.put(("ok", fps))
    except Exception as e:  # reported, and counted as a miss
        out.put(("error", f"{type(e).__name__}: {e}"))


def _rest_phase(base: str, clients: int, seconds: float) -> Record:
    record = Record()
    stop_at = time.perf_counter() + seconds
    threads = [
        threading.Thread(target=post_runs, args=(base, lambda: time.perf_counter() < stop_at, record))
        for _ in range(clients)
    ]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return record


def _cpu_split(pid: int) -> tuple[float, float]:
    """CPU seconds of the API process alone, and of its descendants (the web app)."""
    own = cpu_seconds_single(pid)
    return own, cpu_seconds(pid) - own


def cpu_seconds_single(pid: int) -> float:
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return 0.0


def _wait_web_quiet(pid: int, timeout_s: float) -> float:
    """Wait until the web app's process (the descendants of ``pid``) has finished warming up
    (compiling or loading every system's kernels and matrices in the background): under
    0.05 cores over 2 s.  Returns the seconds waited."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout_s:
        c0 = _cpu_split(pid)[1]
        time.sleep(2)
        if (_cpu_split(pid)[1] - c0) / 2 < 0.05:
            break
    return time.monotonic() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sessions", type=int, default=30, help="headless websocket clients (1..100)")
    ap.add_argument("--rest-clients", type=int, default=4, help="REST clients posting runs (0..32)")
    ap.add_argument("--browsers", type=int, default=2, help="headless Chromium pages (0..8)")
    ap.add_argument("--seconds", type=float, default=60.0, help="the measured window (1..600 s)")
    ap.add_argument("--baseline-seconds", type=float, default=10.0, help="REST alone before the web load")
    ap.add_argument("--web-only-seconds", type=float, default=10.0, help="web load alone (CPU per session)")
    ap.add_argument("--settle-seconds", type=float, default=2.0, help="after every client receives, before measuring")
    ap.add_argument("--warm-timeout", type=float, default=600.0, help="wait at most this for the web app's warm-up")
    ap.add_argument("--min-fps", type=float, default=20.0)
    ap.add_argument("--max-p99-ms", type=float, default=250.0)
    args = ap.parse_args(argv)
    if not (
        1 <= args.sessions <= 100
        and 0 <= args.rest_clients <= 32
        and 0 <= args.browsers <= 8
        and 1 <= args.seconds <= 600
        and 0 <= args.settle_seconds <= 60
        and 0 <= args.baseline_seconds <= 120
        and 0 <= args.web_only_seconds <= 120
    ):
        ap.error(
            "bounds: 1 ≤ sessions ≤ 100, 0 ≤ rest-clients ≤ 32, 0 ≤ browsers ≤ 8, 1 ≤ seconds ≤ 600, "
            "0 ≤ settle-seconds ≤ 60"
        )
    tmp = tempfile.mkdtemp(prefix="nmkane-classroom-")
    proc, base, web_port = start_serve(os.path.join(tmp, "runs.sqlite3"), max_sessions=args.sessions + args.browsers)
    try:
        return _measure(args, proc, base, web_port)
    finally:
        stop_serve(proc)
        shutil.rmtree(tmp, ignore_errors=True)


def _measure(args, proc, base: str, web_port: int) -> int:
    ok = True
    print(f"server   nmkane serve, pids {tree_pids(proc.pid)}, {os.cpu_count()} CPU cores, load {os.getloadavg()}")
    waited = _wait_web_quiet(proc.pid, args.warm_timeout)
    print(f"server   web app warmed up (kernels, matrices) after {waited:.0f} s more")
    rss0 = rss_mib(proc.pid)
    base_p50 = base_p99 = float("nan")
    if args.rest_clients and args.baseline_seconds:
        rec = _rest_phase(base, args.rest_clients, args.baseline_seconds)
        lat = sorted(rec.latencies)
        base_p50, base_p99 = _pct(lat, 0.5), _pct(lat, 0.99)
        print(f"REST     alone: {len(lat)} runs, p50 {base_p50:.0f} ms, p99 {base_p99:.0f} ms")

    ctx = multiprocessing.get_context("spawn")
    out = ctx.Queue()
    settle_max = 120.0
    total = settle_max + args.web_only_seconds + args.seconds + 5
    ready, stop_ws = ctx.Event(), ctx.Event()
    ws = ctx.Process(target=_ws_worker, args=(web_port, args.sessions, total, ready, stop_ws, out), daemon=True)
    t_start = time.monotonic()
    ws.start()
    ready.wait(settle_max)  # every client connected and receiving (its first run computed)
    print(f"web      {args.sessions} websocket clients receiving frames after {time.monotonic() - t_start:.1f} s")
    time.sleep(args.settle_seconds)
    t_web0, cpu_web0 = time.monotonic(), _cpu_split(proc.pid)
    time.sleep(args.web_only_seconds)
    t_web1, cpu_web1 = time.monotonic(), _cpu_split(proc.pid)

    br = None
    if args.browsers:
        br = ctx.Process(
            target=_browser_worker, args=(web_port, args.browsers, time.monotonic(), args.seconds, out), daemon=True
        )
    # the measured window: REST clients, websocket clients, browsers together
    t0, cpu0 = time.monotonic(), _cpu_split(proc.pid)
    if br is not None:
        br.start()
    rec = _rest_phase(base, args.rest_clients, args.seconds) if args.rest_clients else None
    if rec is None:
        time.sleep(args.seconds)
    t1, cpu1 = time.monotonic(), _cpu_split(proc.pid)
    rss1 = rss_mib(proc.pid)
    stop_ws.set()  # the window is over: the websocket clients leave (they used to stay until `total`)

    results = {}
    for _ in range(2 if br is not None else 1):
        item = out.get(timeout=total + 300)
        if isinstance(item, list):
            results["ws"] = item
        else:
            results["br"] = item
    ws.join(10)
    if br is not None:
        br.join(10)

    fps = []
    errors = []
    for frames, error, _, _ in results["ws"]:
        fps.append(sum(1 for t in frames if t0 <= t < t1) / (t1 - t0))
        if error or not frames:
            errors.append(error or "no frame received")
    fps.sort()
    web_s = t_web1 - t_web0
    web_cpu = (cpu_web1[1] - cpu_web0[1]) / web_s
    web_frames = sum(sum(1 for t in frames if t_web0 <= t < t_web1) for frames, _, _, _ in results["ws"])
    ms_per_frame = 1e3 * web_cpu * web_s / max(web_frames, 1)
    print(
        f"web      {args.sessions} websocket clients: frames/s min {fps[0]:.1f}, median {statistics.median(fps):.1f}, "
        f"max {fps[-1]:.1f}; errors {len(errors)} {errors[:3] if errors else ''}"
    )
    print(
        f"web      alone: {web_frames / web_s / args.sessions:.1f} frames/s per client; web app process "
        f"{web_cpu:.2f} cores = {100 * web_cpu / args.sessions:.1f} % of a core per session, "
        f"{ms_per_frame:.2f} ms of CPU per frame delivered (one core animates "
        f"{1e3 / max(ms_per_frame, 1e-3) / (args.min_fps or 20):.0f} sessions at {args.min_fps or 20:g} frames/s); "
        f"API process {(cpu_web1[0] - cpu_web0[0]) / web_s:.2f} cores"
    )
    if br is not None:
        kind, what = results.get("br", ("error", "no answer"))
        if kind == "ok":
            print(
                f"browsers {args.browsers} Chromium pages: frames with motion/s " + ", ".join(f"{f:.1f}" for f in what)
            )
        else:
            print(f"browsers {kind}: {what}")
            ok = ok and kind == "skipped"
    wall = t1 - t0
    print(
        f"cpu      under load: API process {(cpu1[0] - cpu0[0]) / wall:.2f} cores, "
        f"web app process {(cpu1[1] - cpu0[1]) / wall:.2f} cores (of {os.cpu_count()})"
    )
    print(f"memory   server RSS {rss0:.0f} MiB at start, {rss1:.0f} MiB under load (both processes)")
    if rec is not None:
        lat = sorted(rec.latencies)
        p50, p99 = _pct(lat, 0.5), _pct(lat, 0.99)
        non_201 = sum(n for c, n in rec.codes.items() if c != 201)
        print(
            f"REST     under web load: {len(lat)} runs ({len(lat) / wall:.1f}/s), p50 {p50:.0f} ms, p99 {p99:.0f} ms "
            f"(alone: p50 {base_p50:.0f}, p99 {base_p99:.0f}); answers {dict(rec.codes)}, "
            f"errors {dict(rec.errors) or 0}"
        )
        ok = ok and p99 <= args.max_p99_ms and non_201 == 0 and not rec.errors
    ok = ok and fps[0] >= args.min_fps and not errors
    print(f"load     {os.getloadavg()} (other processes on this machine count too)")
    print(
        f"result   {'PASS' if ok else 'FAIL'} (targets: every client ≥ {args.min_fps:g} frames/s, "
        f"REST p99 ≤ {args.max_p99_ms:g} ms, no errors)"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
