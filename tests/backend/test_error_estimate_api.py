"""REST: a run that asks ``error_estimate`` carries it in its document's summary, with the numbers
the library gives; the service refuses one whose second run (at dt/2) passes its step cap."""

from fastapi.testclient import TestClient

from backend import Settings, create_app
from nmkane_core.run.simulate import simulate
from nmkane_core.schema import RunResult
from tests.backend._bodies import error_of

PENDULUM = {"system": "iftomm-a01", "t_final": 2.0, "dt": 0.01}


def test_the_document_carries_the_estimate_of_the_library(client):
    r = client.post("/api/runs", json={**PENDULUM, "error_estimate": True})
    assert r.status_code == 201
    doc = r.json()
    RunResult.model_validate(doc)
    est = doc["summary"]["error_estimate"]
    assert doc["settings"]["error_estimate"] is True
    assert est["method"] == "half step" and est["refined_status"] == "ok" and est["rows"] == len(doc["t"])
    here = simulate({**PENDULUM, "error_estimate": True}, progress=False).summary["error_estimate"]
    assert est["max_abs"] == here["max_abs"] and est["richardson"] == here["richardson"]
    assert set(est["max_abs"]) == set(doc["state"]) and all(v > 0 for v in est["max_abs"].values())
    stored = client.get(f"/api/runs/{doc['id']}").json()
    assert stored["summary"]["error_estimate"] == est
    plain = client.post("/api/runs", json=PENDULUM).json()
    assert plain["summary"]["error_estimate"] is None
    schemas = client.get("/openapi.json").json()["components"]["schemas"]
    assert "error_estimate" in schemas["RunSettings"]["properties"] and "ErrorEstimate" in schemas


def test_the_service_refuses_an_estimate_whose_second_run_passes_its_step_cap(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, max_steps=1000)
    with TestClient(base_url="http://localhost", app=create_app(s)) as c:
        body = {**PENDULUM, "t_final": 8.0}  # 800 steps; 1,600 at dt/2
        err = error_of(c.post("/api/runs", json={**body, "error_estimate": True}))
        assert err["field"] == "error_estimate" and err["reason"] == "its second run at dt/2 would take 1,600 steps"
        assert "dt ≥ 0.016 s" in err["allowed"] and "on this service" in err["allowed"]
        assert c.post("/api/runs", json=body).status_code == 201
