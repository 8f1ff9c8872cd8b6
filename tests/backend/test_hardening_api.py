"""Issue 16, the REST service: error bodies for hostile input, HEAD, content types, the store
cap, DELETE and ``nmkane store prune``, Host allow-list and token, read deadline."""

import socket
import time

import pytest
from fastapi.testclient import TestClient

from backend import Settings, create_app
from backend.errors import ErrorResponse

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 2}


def _client(settings, **kw):
    return TestClient(create_app(settings), base_url="http://localhost", **kw)


@pytest.fixture()
def settings(tmp_path):
    return Settings(data_dir=tmp_path, warm_kernels=False)


@pytest.fixture()
def client(settings):
    with _client(settings, raise_server_exceptions=False) as c:
        yield c


def _error(r, status):
    assert r.status_code == status, r.text[:500]
    ErrorResponse.model_validate(r.json())
    return r.json()["detail"]


def _post(client, raw: bytes, ctype="application/json"):
    return client.post("/api/runs", content=raw, headers={"content-type": ctype})


# ----------------------------------------------------------------------------- hostile bodies
@pytest.mark.parametrize(
    "raw,field",
    [
        (b'{"system": "\\ud800"}', "system"),
        (b'{"params": {"\\ud800": 1}}', "params.\\ud800"),
        (b'{"initial": {"\\udfff\\ud800": 1}}', None),
        (b'{"model": "x\\ud800y"}', None),
    ],
)
def test_lone_surrogates_get_a_4xx_not_a_500(client, raw, field):
    r = _post(client, raw)
    assert 400 <= r.status_code < 500, r.text[:300]
    item = _error(r, r.status_code)[0]
    if field:
        assert item["field"] == field
    r.content.decode("utf-8")  # the body is valid UTF-8


def test_malformed_json_names_the_body_and_the_position_in_the_reason(client):
    item = _error(_post(client, b'{"dt": 0.01,'), 422)[0]
    assert item["field"] == "body" and item["loc"] == ["body"] and "at character 12" in item["reason"]


def test_a_wrong_content_type_is_415_without_a_python_byte_string(client):
    item = _error(_post(client, b'{"dt": 0.01}', "text/plain"), 415)[0]
    assert item["field"] == "content-type" and item["value"] == "text/plain"
    assert "b'" not in item["msg"] and "application/json" in item["allowed"]


def test_huge_values_are_shortened_when_echoed(client):
    item = _error(_post(client, b'{"every": ' + b"9" * 400 + b"}"), 422)[0]
    assert len(item["msg"]) < 300 and "digits" in str(item["value"])
    item = _error(_post(client, b'{"every": ' + b"9" * 5000 + b"}"), 400)[0]  # beyond int()'s limit
    assert "digits" in item["reason"] and len(item["msg"]) < 600


def test_head_on_get_routes_answers_like_get_without_a_body(client):
    for path in ("/api/health", "/api/systems", "/api/runs", "/openapi.json"):
        get, head = client.get(path), client.head(path)
        assert head.status_code == get.status_code == 200 and head.content == b"", path
        assert head.headers["content-type"] == get.headers["content-type"]
    assert client.head("/api/runs/nope").status_code == 404


def test_every_violated_service_limit_in_one_answer(tmp_path):
    with _client(Settings(data_dir=tmp_path, warm_kernels=False, max_steps=1000, max_rows=50)) as c:
        items = _error(c.post("/api/runs", json={**SMALL, "dt": 0.0001, "t_final": 1, "every": 1}), 422)
        assert [i["field"] for i in items] == ["dt", "every"]
        items = _error(c.post("/api/runs", json={**SMALL, "dt": 0.01, "t_final": 10, "every": 1}), 422)  # rows only
        hint = int(items[0]["allowed"].split("≥")[1].split()[0])
        assert c.post("/api/runs", json={**SMALL, "dt": 0.01, "t_final": 10, "every": hint}).status_code == 201
        assert _error(c.post("/api/runs", json={**SMALL, "dt": 0.01, "t_final": 10, "every": hint - 1}), 422)


def test_library_checks_report_every_field_as_items(client):
    items = _error(client.post("/api/runs", json={"dt": 0.0, "t_final": -1.0}), 422)
    assert {i["field"] for i in items} == {"dt", "t_final"}


# ----------------------------------------------------------------------------- the store
def test_a_full_store_refuses_with_507_and_keeps_every_run(tmp_path):
    with _client(Settings(data_dir=tmp_path, warm_kernels=False, max_stored_runs=2)) as c:
        ids = [c.post("/api/runs", json=SMALL).json()["id"] for _ in range(2)]
        item = _error(c.post("/api/runs", json=SMALL), 507)[0]
        assert item["type"] == "store_full" and "2 runs" in item["msg"] and "prune" in item["allowed"]
        assert all(c.get(f"/api/runs/{i}").status_code == 200 for i in ids)
        assert c.delete(f"/api/runs/{ids[0]}").status_code == 204
        assert c.get(f"/api/runs/{ids[0]}").status_code == 404
        assert _error(c.delete(f"/api/runs/{ids[0]}"), 404)[0]["value"] == ids[0]
        assert c.post("/api/runs", json=SMALL).status_code == 201  # room again
        assert c.get("/api/health").json()["runs_stored"] == 2


def test_the_size_cap_counts_bytes(tmp_path):
    with _client(Settings(data_dir=tmp_path / "one", warm_kernels=False)) as c:
        assert c.post("/api/runs", json=SMALL).status_code == 201
        one = c.app.state.service.store.size  # the bytes one stored run takes
    cap = int(3.5 * one)
    with _client(Settings(data_dir=tmp_path / "capped", warm_kernels=False, max_store_bytes=cap)) as c:
        codes = [c.post("/api/runs", json=SMALL).status_code for _ in range(8)]
        assert codes[:3] == [201] * 3 and codes[-1] == 507 and 201 not in codes[codes.index(507) :]
        assert c.app.state.service.store.size <= cap


def test_evict_oldest_makes_room_when_configured(tmp_path):
    with _client(Settings(data_dir=tmp_path, warm_kernels=False, max_stored_runs=3, store_full="evict-oldest")) as c:
        ids = [c.post("/api/runs", json=SMALL).json()["id"] for _ in range(5)]
        listed = [r["id"] for r in c.get("/api/runs").json()["runs"]]
        assert listed == ids[::-1][:3] and c.get(f"/api/runs/{ids[0]}").status_code == 404


def test_bad_store_settings_are_refused():
    with pytest.raises(ValueError, match="store_full"):
        Settings(store_full="delete-everything")
    with pytest.raises(ValueError, match="max_stored_runs"):
        Settings(max_stored_runs=0)


def test_store_prune_command(tmp_path, monkeypatch, capsys):
    from backend.cli import STORE
    from backend.store import RunStore

    db = tmp_path / "runs.sqlite3"
    store = RunStore(db)
    for i in range(5):
        store.add(f"r{i}", "appell-hamel", "ok", {}, {}, b"{}")
    store._db.execute("UPDATE runs SET created = created - 40 * 86400 WHERE id IN ('r0', 'r1')")
    store.close()

    import nmkane_core.cli.commands as commands
    from nmkane_core.cli import main

    monkeypatch.setattr(commands, "contributed", lambda: [STORE])  # the entry point, faked
    commands.all_commands.cache_clear()
    try:
        assert main(["store", "--db", str(db), "prune", "--older-than", "30"]) == 0
        assert "deleted 2 of 5 runs" in capsys.readouterr().out
        assert main(["store", "--db", str(db), "prune", "--keep", "1"]) == 0
        assert "deleted 2 of 3 runs; 1 left" in capsys.readouterr().out
        assert main(["store", "--db", str(db), "info"]) == 0
        assert "1 runs" in capsys.readouterr().out
        assert main(["store", "--db", str(db), "prune", "--keep", "-1"]) == 2
        assert main(["store", "--db", str(tmp_path / "none.sqlite3"), "info"]) == 2
    finally:
        commands.all_commands.cache_clear()
    left = RunStore(db)
    assert [r["id"] for r in left.list(10, 0)] == ["r4"]
    left.close()


# ----------------------------------------------------------------------------- exposure
def test_a_foreign_host_gets_400_loopback_names_and_ip_addresses_pass(settings):
    with TestClient(create_app(settings), base_url="http://evil.example") as c:
        item = _error(c.get("/api/health"), 400)[0]
        assert item["type"] == "host_not_allowed" and "evil.example" in item["value"]
        assert "--allow-host" in item["allowed"]
    for base in ("http://localhost:8000", "http://127.0.0.1:8000", "http://[::1]:8000", "http://10.1.2.3:8000"):
        with TestClient(create_app(settings), base_url=base) as c:
            assert c.get("/api/health").status_code == 200, base


def test_allowed_host_names_can_be_added(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, allowed_hosts=("lab.example",))
    with TestClient(create_app(s), base_url="http://lab.example:8000") as c:
        assert c.get("/api/health").status_code == 200


def test_with_a_token_writes_and_reads_of_runs_need_it_and_the_catalogue_does_not(tmp_path):
    """Issue 44: the stored runs are users' data; with a token (an exposed server) reading them needs
    it too.  The health route, the catalogue and the API's documentation stay open."""
    token = "t" * 32
    with _client(Settings(data_dir=tmp_path, warm_kernels=False, token=token)) as c:
        assert c.get("/api/health").status_code == 200
        assert c.get("/api/systems").status_code == 200 and c.get("/openapi.json").status_code == 200
        r = c.post("/api/runs", json=SMALL)
        assert _error(r, 401)[0]["type"] == "unauthorized" and r.headers["www-authenticate"].startswith("Bearer")
        _error(c.post("/api/runs", json=SMALL, headers={"Authorization": "Bearer wrong"}), 401)
        ok = c.post("/api/runs", json=SMALL, headers={"Authorization": f"Bearer {token}"})
        assert ok.status_code == 201
        run_id, auth = ok.json()["id"], {"Authorization": f"Bearer {token}"}
        for path in ("/api/runs", f"/api/runs/{run_id}", f"/api/runs/{run_id}.csv"):
            assert _error(c.get(path), 401)[0]["type"] == "unauthorized", path
            assert c.get(path, headers=auth).status_code == 200, path
        assert _error(c.get("/api/sweeps/no-such-sweep"), 401)  # refused before it is looked up
        assert c.get("/api/sweeps/no-such-sweep", headers=auth).status_code == 404
        _error(c.delete(f"/api/runs/{ok.json()['id']}"), 401)
        assert c.delete(f"/api/runs/{ok.json()['id']}", headers={"Authorization": f"Bearer {token}"}).status_code == 204


def test_serve_asks_for_a_token_off_loopback_unless_no_auth():
    from backend.serve import _auth

    assert _auth("127.0.0.1", True, Settings(warm_kernels=False)) is None
    assert _auth("localhost", True, Settings(warm_kernels=False)) is None
    token = _auth("0.0.0.0", True, Settings(warm_kernels=False))
    assert token and len(token) >= 24
    assert _auth("0.0.0.0", True, Settings(warm_kernels=False)) != token
    assert _auth("192.168.1.5", False, Settings(warm_kernels=False)) is None


# ----------------------------------------------------------------------------- read deadline
def _run_api(tmp_path, read_timeout, **settings):
    from backend.serve import _start_api

    s = Settings(data_dir=tmp_path, warm_kernels=False, read_timeout_s=read_timeout, **settings)
    server, thread, port = _start_api("127.0.0.1", 0, s)
    return server, thread, port


def _closed_within(sock, seconds) -> tuple[bool, bytes]:
    sock.settimeout(seconds)
    got = b""
    try:
        while True:
            chunk = sock.recv(4096)
            if not chunk:
                return True, got
            got += chunk
    except TimeoutError:
        return False, got
    except ConnectionResetError:
        return True, got


def test_clients_that_stop_sending_are_cut_off(tmp_path):
    server, thread, port = _run_api(tmp_path, 1.0)
    try:
        partial_body = socket.create_connection(("127.0.0.1", port))
        partial_body.sendall(
            b"POST /api/runs HTTP/1.1\r\nHost: localhost\r\nContent-Type: application/json\r\n"
            b'Content-Length: 100\r\n\r\n{"system": '
        )
        partial_head = socket.create_connection(("127.0.0.1", port))
        partial_head.sendall(b"GET /api/health HTTP/1.1\r\nHost: loc")
        silent = socket.create_connection(("127.0.0.1", port))
        t0 = time.monotonic()
        for sock in (partial_body, partial_head, silent):
            closed, got = _closed_within(sock, 6.0)
            assert closed, "the connection stayed open"
            assert b"408" in got.split(b"\r\n", 1)[0], got[:200]
            sock.close()
        assert time.monotonic() - t0 < 6.0
        with socket.create_connection(("127.0.0.1", port)) as ok:  # a prompt client is served
            ok.sendall(b"GET /api/health HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n")
            closed, got = _closed_within(ok, 5.0)
            assert got.startswith(b"HTTP/1.1 200")
    finally:
        server.should_exit = True
        thread.join(15)


def test_a_slow_run_is_not_cut_off_by_the_read_deadline(tmp_path):
    # 40 million steps: the run lasts its whole 2 s wall-time limit on any machine, four times the
    # read deadline (a shorter run could end within the deadline on a fast machine, proving nothing)
    server, thread, port = _run_api(tmp_path, 0.5, max_wall_time_s=2.0, max_steps=40_000_000)
    try:
        import httpx

        r = httpx.post(
            f"http://127.0.0.1:{port}/api/runs",
            timeout=60,
            json={"system": "appell-hamel", "dt": 1e-5, "t_final": 400, "every": 40_000},
        )
        assert r.status_code == 201 and r.json()["summary"]["status"] == "timeout"
        assert r.json()["summary"]["wall_time_s"] >= 2.0 > 0.5
    finally:
        server.should_exit = True
        thread.join(15)


def test_many_stalled_clients_do_not_stay(tmp_path):
    server, thread, port = _run_api(tmp_path, 1.0)
    socks = []
    try:
        for _ in range(100):
            s = socket.create_connection(("127.0.0.1", port))
            s.sendall(b"POST /api/runs HTTP/1.1\r\nHost: localhost\r\nContent-Length: 50\r\n\r\n{")
            socks.append(s)
        # each is cut off 1 s after its request began: waited for, socket by socket, within one deadline
        deadline = time.monotonic() + 30
        alive = 0
        for s in socks:
            closed, _ = _closed_within(s, max(0.2, deadline - time.monotonic()))
            alive += not closed
        assert alive == 0
    finally:
        for s in socks:
            s.close()
        server.should_exit = True
        thread.join(15)


def test_evict_oldest_makes_room_beside_the_sweeps_stored_rows(tmp_path):
    """Issue 44: the sweeps' stored rows count against max_store_bytes, but evict-oldest made room
    for a new run as if the runs were all there is; now it evicts until the new run fits beside
    them, and refuses when even an empty run table would not make room."""
    from backend.store import RunStore, StoreCap, StoreFull

    store = RunStore(tmp_path / "runs.sqlite3", StoreCap(100, 10**9, "evict-oldest"))
    try:
        records = [store.record(f"r{i}", "s", "ok", {"i": i}, {}, b"x" * 2000) for i in range(4)]
        row = len(records[0][3]) + len(records[0][4]) + len(records[0][5])
        for rec in records[:3]:
            store.insert(rec)
        store.cap = StoreCap(100, 4 * row, "evict-oldest")  # room for four runs' rows in all
        store.insert(records[3], reserved=2 * row)  # the sweeps hold two runs' worth: two runs go
        assert sorted(r["id"] for r in store.list(limit=10, offset=0)) == ["r2", "r3"]
        assert store.size + 2 * row <= store.cap.max_bytes
        with pytest.raises(StoreFull):  # the sweeps alone fill the cap: no eviction can help
            store.insert(store.record("r9", "s", "ok", {}, {}, b"x" * 2000), reserved=4 * row)
    finally:
        store.close()


def test_connections_past_the_cap_are_answered_503_and_the_cap_frees_when_they_close(tmp_path, monkeypatch):
    """Issue 44: the REST API holds at most MAX_CONNECTIONS open connections (uvicorn's
    limit_concurrency counts the new one too; idle keep-alive ones included: each slow reader
    holds a piece of a document).  With the cap made 4: three idle keep-alive connections are
    served, a fourth is answered 503, and once one of them closes a new one is served.  Each step
    waits for the server's own state (its connections and requests in flight), not a clock."""
    import backend.serve as serve_module

    monkeypatch.setattr(serve_module, "MAX_CONNECTIONS", 4)
    server, thread, port = _run_api(tmp_path, 30.0)
    state = server.server_state

    def settled(connections: int) -> None:  # no request in flight, this many connections open
        deadline = time.monotonic() + 30  # a safety net only: the state normally settles at once
        while state.tasks or len(state.connections) != connections:
            assert time.monotonic() < deadline, (len(state.tasks), len(state.connections))
            time.sleep(0.01)

    def status_of(sock) -> int:
        sock.sendall(b"GET /api/health HTTP/1.1\r\nHost: localhost\r\n\r\n")
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = sock.recv(4096)
            assert chunk, "closed before answering"
            head += chunk
        return int(head.split(b" ", 2)[1])

    held = []
    try:
        for n in range(3):
            settled(n)
            held.append(socket.create_connection(("127.0.0.1", port), timeout=10))
            assert status_of(held[-1]) == 200  # answered, and kept open (keep-alive)
        settled(3)
        extra = socket.create_connection(("127.0.0.1", port), timeout=10)
        assert status_of(extra) == 503
        extra.close()
        held.pop().close()
        settled(2)
        fresh = socket.create_connection(("127.0.0.1", port), timeout=10)
        assert status_of(fresh) == 200
        fresh.close()
    finally:
        for sock in held:
            sock.close()
        serve_module._stop_api(server, thread)
