"""REST service: create, fetch, list, CSV, every error class, limits, restart."""

import csv
import io
import warnings

import pytest

warnings.filterwarnings("ignore", message=".*httpx.*")
from fastapi.testclient import TestClient  # noqa: E402

from backend import Settings, create_app  # noqa: E402

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 20}


@pytest.fixture()
def settings(tmp_path):
    return Settings(data_dir=tmp_path, warm_kernels=False)


@pytest.fixture()
def client(settings):
    with TestClient(create_app(settings)) as c:
        yield c


def test_create_fetch_list_and_csv(client):
    r = client.post("/api/runs", json=SMALL)
    assert r.status_code == 201
    doc = r.json()
    assert set(doc) >= {"id", "system", "settings", "t", "state", "energy", "violation", "summary"}
    assert doc["summary"]["status"] == "ok" and len(doc["t"]) == 2001
    assert doc["settings"]["params"]["rho"] == 5.0 and doc["settings"]["integrator"] == "kutta-merson"
    assert r.headers["location"] == f"/api/runs/{doc['id']}"
    assert len(doc["id"]) >= 20                                   # unguessable ids
    again = client.get(f"/api/runs/{doc['id']}").json()
    assert again == doc
    listing = client.get("/api/runs").json()["runs"]
    assert listing[0]["id"] == doc["id"] and listing[0]["summary"]["status"] == "ok"
    text = client.get(f"/api/runs/{doc['id']}.csv")
    assert text.status_code == 200 and text.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(text.text)))
    assert rows[0][:3] == ["t", "theta", "phi"] and len(rows) == 2002
    assert float(rows[-1][0]) == 20.0


def test_health_and_systems_expose_limits(client):
    assert client.get("/api/health").json()["status"] == "ok"
    data = client.get("/api/systems").json()
    names = {s["name"] for s in data["systems"]}
    assert names == {"appell-hamel", "sliding-particle"}
    ah = next(s for s in data["systems"] if s["name"] == "appell-hamel")
    assert ah["models"] == ["nonlinear", "linear"]
    assert ah["constraint_names"]["nonlinear"] == ["rolling_speed", "no_side_slip", "thread"]
    assert {p["name"]: p["default"] for p in ah["parameters"]}["rho"] == 5.0
    assert set(data["service_limits"]) >= {"max_steps", "max_rows", "max_request_bytes", "max_wall_time_s",
                                           "queue_limit", "max_concurrent_runs"}
    assert "kutta-merson" in data["integrators"]


@pytest.mark.parametrize("body,loc", [
    ({"system": "nope"}, ["body", "system"]),
    ({"system": "appell-hamel", "model": "cubic"}, ["body", "model"]),
    ({"system": "appell-hamel", "dt": 0}, ["body", "dt"]),
    ({"system": "appell-hamel", "dt": -0.01}, ["body", "dt"]),
    ({"system": "appell-hamel", "dt": "fast"}, ["body", "dt"]),
    ({"system": "appell-hamel", "t_final": 0}, ["body", "t_final"]),
    ({"system": "appell-hamel", "dt": 1e-5, "t_final": 100, "every": 100}, ["body", "dt"]),
    ({"system": "appell-hamel", "params": {"rho": -1}}, ["body", "params", "rho"]),
    ({"system": "appell-hamel", "initial": {"u3": 7}}, ["body", "initial", "u3"]),
    ({"system": "appell-hamel", "initial": {"theta": 0, "phi": 0, "x": 0, "y": 0, "z": 30, "u1": 1, "u2": 1,
                                            "u3": 2, "u4": 5, "u5": -0.5}}, ["body", "initial"]),
    ({"system": "appell-hamel", "color": "red"}, ["body", "color"]),
    ({"system": "appell-hamel", "integrator": "euler"}, ["body", "integrator"]),
])
def test_bad_input_gets_422_with_field_path_value_and_reason(client, body, loc):
    r = client.post("/api/runs", json=body)
    assert r.status_code == 422, r.text
    err = r.json()["detail"][0]
    assert err["loc"] == loc
    assert err["msg"] and "input" in err


@pytest.mark.parametrize("raw", [b'{"system": "appell-hamel", "dt": NaN}', b'{"system": "appell-hamel", "t_final": Infinity}',
                                 b'{"system": "appell-hamel", "gamma": -Infinity}'])
def test_nan_and_infinity_in_json_get_422(client, raw):
    r = client.post("/api/runs", content=raw, headers={"content-type": "application/json"})
    assert r.status_code == 422
    assert r.json()["detail"][0]["loc"][0] == "body"


def test_hostile_bodies_get_4xx_never_5xx(client):
    cases = [b"[" * 20000, b'{"system": "' + b"a" * 60000 + b'"}', b"not json", b"",
             b'{"system": 1e999999}', b'{"params": {"rho": 1e308}}', b"\xff\xfe\x00"]
    for raw in cases:
        r = client.post("/api/runs", content=raw, headers={"content-type": "application/json"})
        assert 400 <= r.status_code < 500, (raw[:20], r.status_code)
    r = client.post("/api/runs", content=b"system=appell-hamel", headers={"content-type": "text/plain"})
    assert 400 <= r.status_code < 500


def test_oversized_body_gets_413(client):
    big = {"system": "appell-hamel", "initial": {f"k{i}": 0.0 for i in range(10000)}}
    assert client.post("/api/runs", json=big).status_code == 413


def test_singular_run_is_a_normal_result(client):
    r = client.post("/api/runs", json={"system": "appell-hamel", "initial": {"u2": 0}, "switching": False})
    assert r.status_code == 201 and r.json()["summary"]["status"] == "singular"


def test_run_past_wall_time_limit_ends_with_status_timeout(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, max_wall_time_s=0.05)
    with TestClient(create_app(s)) as c:
        r = c.post("/api/runs", json={"system": "appell-hamel", "dt": 0.0005, "t_final": 900, "every": 1000})
        assert r.status_code == 201
        doc = r.json()
        assert doc["summary"]["status"] == "timeout" and 0 < doc["t"][-1] < 900


def test_service_step_cap_refuses_before_running(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, max_steps=1000)
    with TestClient(create_app(s)) as c:
        r = c.post("/api/runs", json={"system": "appell-hamel", "dt": 0.01, "t_final": 20})
        assert r.status_code == 422 and r.json()["detail"][0]["loc"] == ["body", "dt"]
        assert "1,000" in r.json()["detail"][0]["allowed"]


def test_past_queue_limit_answers_503_with_retry_after(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, queue_limit=0)
    with TestClient(create_app(s)) as c:
        r = c.post("/api/runs", json=SMALL)
        assert r.status_code == 503 and r.headers["retry-after"] == "1"


def test_unknown_run_is_404(client):
    assert client.get("/api/runs/doesnotexist").status_code == 404
    assert client.get("/api/runs/doesnotexist.csv").status_code == 404


def test_runs_survive_a_restart(settings):
    with TestClient(create_app(settings)) as c:
        ids = [c.post("/api/runs", json={**SMALL, "t_final": 1}).json()["id"] for _ in range(3)]
    with TestClient(create_app(settings)) as c:
        for run_id in ids:
            doc = c.get(f"/api/runs/{run_id}").json()
            assert doc["id"] == run_id and doc["summary"]["status"] == "ok"
        assert c.get("/api/health").json()["runs_stored"] == 3


def test_cors_is_closed_by_default(client):
    r = client.options("/api/runs", headers={"Origin": "http://evil.example", "Access-Control-Request-Method": "POST"})
    assert "access-control-allow-origin" not in r.headers
