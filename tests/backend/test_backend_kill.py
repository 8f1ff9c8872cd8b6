"""A server killed with SIGKILL during runs loses no acknowledged run and leaves no partial one."""

import signal
import sqlite3
import threading
import time

import httpx

from backend.store import RunStore
from nmkane_core.schema import RunResult
from tests._helpers import start_backend

RUN = {"system": "appell-hamel", "dt": 0.005, "t_final": 20}  # 4001 rows


def _start(db):
    return start_backend(db, {"NMKANE_MAX_CONCURRENT_RUNS": "2"})


def test_sigkill_during_runs_loses_no_acknowledged_run_and_leaves_no_partial_one(tmp_path):
    db = tmp_path / "runs.sqlite3"
    server, port = _start(db)
    acked, lock, stop = {}, threading.Lock(), threading.Event()

    def client():
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as c:
            while not stop.is_set():
                try:
                    r = c.post("/api/runs", json=RUN)
                except httpx.HTTPError:
                    return  # the server is gone
                if r.status_code == 201:
                    with lock:
                        acked[r.json()["id"]] = r.content

    threads = [threading.Thread(target=client) for _ in range(8)]
    for th in threads:
        th.start()
    deadline = time.time() + 30
    while len(acked) < 30 and time.time() < deadline:  # killed in full flow, runs in flight
        time.sleep(0.05)
    server.kill()  # SIGKILL
    stop.set()
    for th in threads:
        th.join(30)
    assert len(acked) >= 30

    # the file is a sound database; every row is a whole, valid run document
    con = sqlite3.connect(db)
    assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    con.close()
    store = RunStore(db)
    try:
        ids = [r["id"] for r in store.list(limit=10**6, offset=0)]
        assert store.count() == len(ids) >= len(acked)
        for run_id in ids:
            doc = RunResult.model_validate_json(store.document(run_id))
            assert doc.id == run_id and doc.summary.status == "ok"
            assert len(doc.t) == 4001 and doc.t[-1] == 20.0 and all(len(v) == 4001 for v in doc.state.values())
        assert set(acked) <= set(ids)  # no acknowledged run lost
    finally:
        store.close()

    # and a restarted server serves each acknowledged run exactly as it was acknowledged
    server, port = _start(db)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=10) as c:
            for run_id, content in acked.items():
                assert c.get(f"/api/runs/{run_id}").content == content
            assert c.post("/api/runs", json=RUN).status_code == 201
    finally:
        assert server.stop(signal.SIGTERM, timeout=30)[0] == 0
