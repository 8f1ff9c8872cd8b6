"""The forces at points through the service: listed per model by GET /api/systems, in the run
document and its CSV (temporary database)."""

import csv
import io

import pytest
from fastapi.testclient import TestClient

from backend import Settings, create_app


@pytest.fixture()
def client(tmp_path):
    with TestClient(base_url="http://localhost", app=create_app(Settings(data_dir=tmp_path, warm_kernels=False))) as c:
        yield c


def test_systems_list_the_forces_each_model_declares(client):
    data = {s["name"]: s for s in client.get("/api/systems").json()["systems"]}
    ah = {f["name"]: f for f in data["appell-hamel"]["forces"]["linear"]}
    assert ah["thread"]["components"] == ["thread.tension"] and ah["contact"]["route"] == "multipliers"
    assert ah["contact"]["on"] and ah["contact"]["unit"] == "N"
    assert [f["route"] for f in data["sliding-particle"]["forces"]["minimal"]] == ["newton"]
    bike = data["whipple-bicycle"]["forces"]["default"]
    assert [f["name"] for f in bike] == ["rear_tyre", "front_tyre"]
    assert bike[0]["components"] == ["rear_tyre.longitudinal", "rear_tyre.lateral", "rear_tyre.normal"]


def test_run_document_and_csv_carry_the_forces_at_points(client):
    doc = client.post("/api/runs", json={"system": "knife-edge", "t_final": 1.0}).json()
    assert doc["point_forces"]["blade.lateral"] == pytest.approx([0.5] * len(doc["t"]), rel=1e-12)
    assert doc["summary"]["max_abs_point_force"] == {"blade": pytest.approx(0.5, rel=1e-12)}
    assert doc["constraint_forces"]["u2"] == pytest.approx(doc["point_forces"]["blade.lateral"], rel=1e-12)
    rows = list(csv.reader(io.StringIO(client.get(f"/api/runs/{doc['id']}.csv").text)))
    assert rows[0][-1] == "blade.lateral" and float(rows[1][-1]) == pytest.approx(0.5, rel=1e-12)
    off = client.post("/api/runs", json={"system": "knife-edge", "t_final": 1.0, "constraint_forces": False}).json()
    assert off["point_forces"] == {} and off["constraint_forces"] == {}
