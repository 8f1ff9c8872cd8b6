"""A server killed with SIGKILL during runs loses no acknowledged run and leaves no partial one."""

import os
import signal
import socket
import sqlite3
import subprocess
import sys
import threading
import time
import zlib

import httpx
import orjson


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _start(db, port):
    env = {**os.environ, "NMKANE_DB": str(db), "NMKANE_MAX_CONCURRENT_RUNS": "2"}
    proc = subprocess.Popen([sys.executable, "-m", "backend", "--port", str(port)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    deadline = time.time() + 120
    while time.time() < deadline:
        try:
            if httpx.get(f"http://127.0.0.1:{port}/api/health", timeout=1).status_code == 200:
                return proc
        except httpx.HTTPError:
            time.sleep(0.2)
    proc.kill()
    raise RuntimeError("server did not start")


def test_sigkill_during_runs_loses_no_acknowledged_run(tmp_path):
    db = tmp_path / "runs.sqlite3"
    port = _free_port()
    proc = _start(db, port)
    acked, lock, stop = [], threading.Lock(), threading.Event()

    def client():
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as c:
            while not stop.is_set():
                try:
                    r = c.post("/api/runs", json={"system": "appell-hamel", "dt": 0.005, "t_final": 20})
                except httpx.HTTPError:
                    return
                if r.status_code == 201:
                    with lock:
                        acked.append(r.json()["id"])

    threads = [threading.Thread(target=client) for _ in range(6)]
    for th in threads:
        th.start()
    time.sleep(3.0)
    proc.send_signal(signal.SIGKILL)
    proc.wait(10)
    stop.set()
    for th in threads:
        th.join(30)
    assert len(acked) > 5
    # every acknowledged run is there and complete; nothing half-written exists
    con = sqlite3.connect(db)
    rows = con.execute("SELECT id, document FROM runs").fetchall()
    con.close()
    stored = {}
    for run_id, blob in rows:
        doc = orjson.loads(zlib.decompress(blob))        # a partial row would not decompress/parse
        assert doc["id"] == run_id and len(doc["t"]) == 4001
        stored[run_id] = doc
    assert set(acked) <= set(stored)
    # and a restarted server serves them
    proc = _start(db, port)
    try:
        for run_id in acked[:5]:
            assert httpx.get(f"http://127.0.0.1:{port}/api/runs/{run_id}", timeout=10).json()["id"] == run_id
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.wait(20)
