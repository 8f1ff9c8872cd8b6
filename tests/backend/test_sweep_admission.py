"""Issue 44, item 2: sweeps under the service's admission.

At most ``max_sweeps`` sweeps are admitted (a further POST answers 503 with a Retry-After from
the backlog), ``/api/health`` counts them, a sweep leaves the run workers to interactive runs
(checked by the order of events, not by wall time), and a sweep's rows count against
``max_store_bytes``; a sweep whose rows or end cannot be written ends ``failed`` with the
store's message.

A sweep is held still with a gate: every sweep run (``run_point``, which the service's sweeps
call through ``run_batch``) records its start, then waits for the gate; interactive runs
record theirs (``backend.service.simulate``).  Conditions are waited for by bounded polling.
"""

import math
import threading
import time

import pytest
from fastapi.testclient import TestClient

import backend.service as service_module
import nmkane_core.sweep.executors as executors
from backend import Settings, create_app
from backend.store_disk import StoreDiskFull, disk_full

SMALL = {"system": "sliding-particle", "t_final": 0.05}


def _sweep(runs: int) -> dict:
    return {"settings": SMALL, "grid": [f"gamma1=-40:-10:{runs}"]}


class Events:
    """Starts of sweep runs and interactive runs, in order; sweep runs wait for ``gate``."""

    def __init__(self, monkeypatch):
        self.log: list[str] = []
        self.lock = threading.Lock()
        self.gate = threading.Event()
        point, simulate = executors.run_point, service_module.simulate

        def gated_point(*args, **kw):
            self.add("sweep")
            assert self.gate.wait(60), "the test's gate was never opened"
            return point(*args, **kw)

        def recorded_simulate(*args, **kw):
            self.add("run")
            return simulate(*args, **kw)

        monkeypatch.setattr(executors, "run_point", gated_point)
        monkeypatch.setattr(service_module, "simulate", recorded_simulate)

    def add(self, what: str) -> None:
        with self.lock:
            self.log.append(what)

    def snapshot(self) -> list[str]:
        with self.lock:
            return list(self.log)


def _until(condition, what: str, timeout: float = 60.0):
    deadline = time.monotonic() + timeout
    while not (value := condition()):
        if time.monotonic() > deadline:
            raise AssertionError(f"not within {timeout} s: {what}")
        time.sleep(0.01)
    return value


def _client(tmp_path, **settings):
    app = create_app(Settings(data_dir=tmp_path, warm_kernels=False, **settings))
    return TestClient(app, base_url="http://localhost", raise_server_exceptions=False)


def _ended(c, sweep_id: str) -> dict:
    return _until(
        lambda: (
            (s := c.get(f"/api/sweeps/{sweep_id}", params={"limit": 1}).json())["status"] not in ("queued", "running")
            and s
        ),
        f"sweep {sweep_id} ended",
    )


def _refused_burst(tmp_path, monkeypatch, runs: int) -> tuple[list, dict]:
    """A burst of 10 sweeps of ``runs`` runs while the first is held: the answers and the health."""
    events = Events(monkeypatch)
    with _client(tmp_path / str(runs), max_concurrent_runs=2) as c:
        try:
            answers = [c.post("/api/sweeps", json=_sweep(runs))]
            _until(lambda: "sweep" in events.snapshot(), "the first sweep's run started")
            answers += [c.post("/api/sweeps", json=_sweep(runs)) for _ in range(9)]
            health = c.get("/api/health").json()
        finally:
            events.gate.set()
        for r in answers:
            if r.status_code == 202:
                _ended(c, r.json()["id"])
        assert c.get("/api/health").json()["sweep_runs_pending"] == 0
    return answers, health


def test_sweeps_past_max_sweeps_get_503_with_a_retry_after_from_their_backlog(tmp_path, monkeypatch):
    waits = {}
    for runs in (200, 800):
        answers, health = _refused_burst(tmp_path, monkeypatch, runs)
        codes = [r.status_code for r in answers]
        assert codes == [202, 202] + [503] * 8, codes  # max_sweeps = 2 (the default): one running, one queued
        refused = answers[2]
        assert refused.json()["detail"][0]["type"] == "overloaded"
        waits[runs] = int(refused.headers["Retry-After"])
        # the running sweep's remaining runs × the seconds per run (none measured yet: the prior) ÷ its workers
        assert waits[runs] == math.ceil(runs * service_module.SweepAdmission(2, 1).mean_run_s / health["sweep_workers"])
        assert health["sweep_workers"] == 1
    assert waits[800] > waits[200] >= 10  # the backlog, not a constant


def test_health_counts_the_sweeps_running_queued_and_their_runs(tmp_path, monkeypatch):
    events = Events(monkeypatch)
    with _client(tmp_path, max_concurrent_runs=2) as c:
        try:
            ids = [c.post("/api/sweeps", json=_sweep(n)).json()["id"] for n in (30, 20)]
            _until(lambda: "sweep" in events.snapshot(), "the first sweep's run started")
            h = c.get("/api/health").json()
            assert (h["sweeps_running"], h["sweeps_queued"], h["sweep_runs_pending"]) == (1, 1, 50)
            assert h["sweep_runs_running"] == 1 and h["max_sweeps"] == 2  # the sweep's share of the 2 workers
        finally:
            events.gate.set()
        assert [_ended(c, i)["status"] for i in ids] == ["done", "done"]
        h = c.get("/api/health").json()
        assert (h["sweeps_running"], h["sweeps_queued"], h["sweep_runs_pending"], h["sweep_runs_running"]) == (
            0,
            0,
            0,
            0,
        )


@pytest.mark.parametrize("workers", [1, 2])
def test_an_interactive_run_starts_before_the_sweeps_remaining_runs(tmp_path, monkeypatch, workers):
    """With the sweep holding its worker(s), an interactive run is submitted: at most one sweep
    run per sweep worker may start between its submission and its start (runs first)."""
    events = Events(monkeypatch)
    with _client(tmp_path, max_concurrent_runs=workers) as c:
        svc = c.app.state.service
        answer: list = []
        try:
            sweep_id = c.post("/api/sweeps", json=_sweep(300)).json()["id"]
            _until(lambda: "sweep" in events.snapshot(), "the sweep's first run started")
            before = len(events.snapshot())
            post = threading.Thread(target=lambda: answer.append(c.post("/api/runs", json=SMALL)))
            post.start()
            # the run started, or waits in the pool's queue behind the sweep
            _until(
                lambda: "run" in events.snapshot() or (svc.admitted and svc.pool._work_queue.qsize()),
                "the run started or queued",
            )
        finally:
            events.gate.set()
        post.join(60)
        assert answer and answer[0].status_code == 201, answer
        log = events.snapshot()
        between = log[before : log.index("run")].count("sweep")
        assert between <= 1, f"{between} sweep runs started while the interactive run waited: {log[:80]}"
        assert _ended(c, sweep_id)["status"] == "done"


def test_sweep_rows_past_the_store_cap_stop_the_sweep_saying_so(tmp_path):
    with _client(tmp_path, max_store_bytes=6_000) as c:
        r = c.post("/api/sweeps", json=_sweep(100))
        assert r.status_code == 202, r.text
        st = _ended(c, r.json()["id"])
        assert st["status"] == "failed", st
        assert "store is full" in st["message"] and "of 100 runs" in st["message"], st["message"]
        assert 0 < st["done"] < 100
        assert c.app.state.sweeps.store.size() <= 6_000
        again = c.post("/api/sweeps", json=_sweep(100))  # the cap is reached: refused before it starts
        assert again.status_code == 507, again.text
        h = c.get("/api/health").json()
        assert (h["sweeps_running"], h["sweeps_queued"], h["sweep_runs_pending"]) == (0, 0, 0)


def test_a_sweep_whose_rows_and_end_cannot_be_written_ends_failed_with_the_stores_message(tmp_path, monkeypatch):
    with _client(tmp_path) as c:
        store = c.app.state.sweeps.store
        full = disk_full(store.path, 0)
        set_status = store.set_status

        def rows_on_a_full_disk(*args, **kw):
            raise full

        def status_on_a_full_disk(sweep_id, status, message=""):
            if status != "running":
                raise StoreDiskFull(store.path, full.reason, full.remedy)
            set_status(sweep_id, status, message)

        monkeypatch.setattr(store, "add_rows", rows_on_a_full_disk)
        monkeypatch.setattr(store, "set_status", status_on_a_full_disk)
        sweep_id = c.post("/api/sweeps", json=_sweep(20)).json()["id"]
        st = _ended(c, sweep_id)
        assert st["status"] == "failed" and "the disk is full" in st["message"] and str(store.path) in st["message"]
        assert c.get("/api/health").json()["sweeps_running"] == 0
        monkeypatch.setattr(store, "set_status", set_status)  # room again: the end is written
        assert c.get(f"/api/sweeps/{sweep_id}").json()["status"] == "failed"
        assert store.get(sweep_id)["status"] == "failed"
