"""A REST sweep whose server is killed is marked ``interrupted`` when the service starts again
(not left ``running`` forever); its rows so far stay readable, and new sweeps run."""

import sqlite3
import time

import httpx

from backend.sweeps import SweepStore, owner_alive, process_owner
from tests._helpers import start_backend

LONG = {  # 500 runs of 5000 steps: still running when the server is killed
    "settings": {"system": "appell-hamel", "dt": 0.001, "t_final": 5},
    "grid": ["gamma=-50:0:50", "gamma1=-20:0:10"],
}
SHORT = {"settings": {"system": "appell-hamel", "dt": 0.01, "t_final": 1}, "grid": ["gamma=-10,0"]}


def _wait(c, sweep_id, until, timeout=300):
    deadline = time.time() + timeout
    while time.time() < deadline:
        st = c.get(f"/api/sweeps/{sweep_id}", params={"limit": 1}).json()
        if until(st):
            return st
        time.sleep(0.1)
    raise AssertionError(f"sweep {sweep_id}: {st}")


def test_a_killed_servers_sweep_is_interrupted_after_restart(tmp_path):
    db = tmp_path / "runs.sqlite3"
    server, port = start_backend(db)
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as c:
            r = c.post("/api/sweeps", json=LONG)
            assert r.status_code == 202, r.text
            sweep_id = r.json()["id"]
            st = _wait(c, sweep_id, lambda s: s["status"] == "running" and s["done"] > 0)
            assert st["done"] < st["total"] == 500
    finally:
        server.kill()  # SIGKILL
    con = sqlite3.connect(db)
    assert con.execute("SELECT status FROM sweeps WHERE id = ?", (sweep_id,)).fetchone()[0] == "running"
    con.close()

    server, port = start_backend(db)  # the same file: the service starts again
    try:
        with httpx.Client(base_url=f"http://127.0.0.1:{port}", timeout=30) as c:
            con = sqlite3.connect(db)  # marked at start, before any sweep request
            assert con.execute("SELECT status FROM sweeps WHERE id = ?", (sweep_id,)).fetchone()[0] == "interrupted"
            con.close()
            st = c.get(f"/api/sweeps/{sweep_id}", params={"limit": 10_000}).json()
            assert st["status"] == "interrupted"
            assert f"after {st['done']} of 500 runs" in st["message"] and "POST the request again" in st["message"]
            assert 0 < st["done"] < 500 and len(st["rows"]) == st["done"]  # every stored row readable
            assert all(row["status"] == "ok" for row in st["rows"])
            assert c.get(f"/api/sweeps/{sweep_id}.csv").text.count("\n") == st["done"] + 1

            r = c.post("/api/sweeps", json=SHORT)  # the restarted service runs sweeps
            assert r.status_code == 202
            new = _wait(c, r.json()["id"], lambda s: s["status"] not in ("queued", "running"))
            assert new["status"] == "done" and new["done"] == 2
            # and its own running sweep is not touched by another store opening the file
            assert SweepStore(db).interrupted == []
    finally:
        server.kill()


def test_owner_liveness(tmp_path):
    me = process_owner()
    assert owner_alive(me)
    host, pid, start = me.split(":")
    assert not owner_alive(f"{host}:{pid}:{start}9")  # the pid reused by a later process
    assert not owner_alive(f"{host}:999999999:1")  # no such process
    assert not owner_alive("other-host:1:1") and not owner_alive("")  # another machine, or a file from before
    db = tmp_path / "s.sqlite3"
    store = SweepStore(db)
    store.create("mine", "appell-hamel", 3, {}, ["gamma"])
    store.create("gone", "appell-hamel", 3, {}, ["gamma"])
    store.set_status("mine", "running")
    store.set_status("gone", "running")
    con = sqlite3.connect(db)
    con.execute("UPDATE sweeps SET owner = ? WHERE id = 'gone'", (f"{host}:999999999:1",))
    con.commit()
    con.close()
    assert SweepStore(db).interrupted == ["gone"]
    assert store.get("mine")["status"] == "running" and store.get("gone")["status"] == "interrupted"
