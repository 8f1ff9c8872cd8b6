"""REST service: create, fetch, list, CSV and every error class (temporary DBs).

Limits and restarts: test_backend_limits.py."""

import csv
import io
import math
import re

import orjson
import pytest

from backend.service import encode_document
from nmkane_core.run.simulate import simulate
from nmkane_core.schema import RunResult
from tests.backend._bodies import SMALL
from tests.backend._bodies import error_of as _error


# --------------------------------------------------------------------------- the happy path
def test_create_fetch_list_and_csv(client):
    r = client.post("/api/runs", json=SMALL)
    assert r.status_code == 201
    doc = r.json()
    RunResult.model_validate(doc)
    assert doc["summary"]["status"] == "ok" and len(doc["t"]) == 2001 and len(doc["state"]) == 10
    assert doc["settings"]["params"]["rho"] == 5.0 and doc["settings"]["integrator"] == "kutta-merson"
    assert r.headers["location"] == f"/api/runs/{doc['id']}"
    assert re.fullmatch(r"[A-Za-z0-9_-]{22,}", doc["id"])  # 128 random bits, URL-safe

    again = client.get(f"/api/runs/{doc['id']}")
    assert again.status_code == 200 and again.content == r.content  # served exactly as acknowledged

    listing = client.get("/api/runs").json()
    assert listing["total"] == 1 and listing["runs"][0]["id"] == doc["id"]
    assert listing["runs"][0]["summary"] == doc["summary"] and listing["runs"][0]["settings"] == doc["settings"]
    assert re.fullmatch(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z", listing["runs"][0]["created"])

    text = client.get(f"/api/runs/{doc['id']}.csv")
    assert text.status_code == 200 and text.headers["content-type"].startswith("text/csv")
    rows = list(csv.reader(io.StringIO(text.text)))
    forces = [*(f"force_{k}" for k in doc["constraint_forces"]), *(f"multiplier_{k}" for k in doc["multipliers"])]
    assert rows[0] == [
        "t",
        *doc["state"],
        "energy",
        *(f"violation_{k}" for k in doc["violation"]),
        *forces,
        *doc["point_forces"],
    ]
    assert len(rows) == 2002 and float(rows[-1][0]) == 20.0
    assert [float(v) for v in rows[1:][1000][1:3]] == [doc["state"]["theta"][1000], doc["state"]["phi"][1000]]


def test_rest_document_and_csv_are_the_core_run_result_and_csv():
    run = simulate(SMALL, progress=False)
    assert orjson.loads(encode_document(run, "abc")) == run.document("abc").model_dump(mode="json", by_alias=True)


def test_csv_export_equals_the_cli_csv(client):
    doc = client.post("/api/runs", json={**SMALL, "t_final": 2}).json()
    assert client.get(f"/api/runs/{doc['id']}.csv").text == simulate({**SMALL, "t_final": 2}, progress=False).to_csv()


def test_list_pages_newest_first_and_filters(client):
    ids = [client.post("/api/runs", json={**SMALL, "t_final": 0.5}).json()["id"] for _ in range(3)]
    ids.append(client.post("/api/runs", json={"system": "sliding-particle", "t_final": 0.5}).json()["id"])
    page = client.get("/api/runs", params={"limit": 2, "offset": 1}).json()
    assert [r["id"] for r in page["runs"]] == ids[::-1][1:3] and page["total"] == 4
    only = client.get("/api/runs", params={"system": "sliding-particle"}).json()
    assert [r["id"] for r in only["runs"]] == ids[3:] and only["total"] == 1
    assert client.get("/api/runs", params={"status": "diverged"}).json()["total"] == 0
    _error(client.get("/api/runs", params={"limit": 0}))
    _error(client.get("/api/runs", params={"status": "great"}))


def test_health_and_systems_expose_the_limits(client):
    h = client.get("/api/health").json()
    assert h["status"] == "ok" and h["runs_stored"] == 0 and h["runs_in_flight"] == 0
    data = client.get("/api/systems").json()
    ah = next(s for s in data["systems"] if s["name"] == "appell-hamel")
    from nmkane_core import system_names

    assert {s["name"] for s in data["systems"]} == set(system_names())
    assert {"appell-hamel", "sliding-particle", "knife-edge", "whipple-bicycle"} <= set(system_names())
    assert ah["models"] == ["nonlinear", "linear"]
    assert ah["constraint_names"]["nonlinear"] == ["rolling_speed", "no_side_slip", "thread"]
    assert {p["name"]: p["default"] for p in ah["parameters"]}["rho"] == 5.0
    sp = next(s for s in data["systems"] if s["name"] == "sliding-particle")
    assert sp["formulations"] == ["nonminimal", "minimal"]
    limits = data["service_limits"]
    assert (
        set(limits)
        == set(data["service_limit_descriptions"])
        == {
            "max_steps",
            "max_rows",
            "max_request_bytes",
            "max_wall_time_s",
            "queue_limit",
            "max_concurrent_runs",
            "max_stored_runs",
            "max_store_bytes",
            "read_timeout_s",
            "max_sweep_runs",
            "max_sweeps",
        }
    )
    assert limits["max_request_bytes"] == 65_536 and limits["max_sweeps"] == 2 and limits["max_sweep_runs"] == 10_000
    assert "kutta-merson" in data["integrators"] and set(data["projections"]) == {"none", "blajer", "yoon"}


def test_openapi_documents_runs_as_the_run_result_schema(client):
    spec = client.get("/openapi.json").json()
    post = spec["paths"]["/api/runs"]["post"]
    assert post["requestBody"]["content"]["application/json"]["schema"]["$ref"].endswith("/RunSettings")
    assert post["responses"]["201"]["content"]["application/json"]["schema"]["$ref"].endswith("/RunResult")
    assert post["responses"]["422"]["content"]["application/json"]["schema"]["$ref"].endswith("/ErrorResponse")
    get = spec["paths"]["/api/runs/{run_id}"]["get"]
    assert get["responses"]["200"]["content"]["application/json"]["schema"]["$ref"].endswith("/RunResult")
    docs = client.get("/docs")
    assert docs.status_code == 200
    for asset in re.findall(r'(?:src|href)="(/static-offline-docs/[^"]+)"', docs.text):  # no CDN: works offline
        assert client.get(asset).status_code == 200, asset
    assert "swagger-ui-bundle.js" in docs.text and "cdn." not in docs.text


# --------------------------------------------------------------------------- bad input -> 422
@pytest.mark.parametrize(
    "body,field,kind",
    [
        ({"system": "nope"}, "system", "value_error"),  # unknown system
        ({"system": "appell-hamel", "model": "cubic"}, "model", "value_error"),  # unknown model
        ({"system": "appell-hamel", "formulation": "minimal"}, "formulation", "value_error"),  # other system's
        ({"system": "appell-hamel", "integrator": "euler"}, "integrator", "value_error"),
        ({"system": "appell-hamel", "dt": "fast"}, "dt", "float_type"),  # wrong types
        ({"system": "appell-hamel", "dt": "0.01"}, "dt", "float_type"),
        ({"system": "appell-hamel", "t_final": True}, "t_final", "float_type"),
        ({"system": "appell-hamel", "every": 2.5}, "every", "int_type"),
        ({"system": "appell-hamel", "params": ["rho", 1]}, "params", "dict_type"),
        ({"system": 7}, "system", "string_type"),
        ({"system": "appell-hamel", "dt": 0}, "dt", "greater_than_equal"),  # dt < min_dt
        ({"system": "appell-hamel", "dt": -0.01}, "dt", "greater_than_equal"),
        ({"system": "appell-hamel", "t_final": 0}, "t_final", "greater_than"),
        ({"system": "appell-hamel", "dt": 1e-6, "t_final": 100, "every": 1000}, "dt", "value_error"),  # steps cap
        ({"system": "appell-hamel", "params": {"rho": -1}}, "params.rho", "value_error"),
        ({"system": "appell-hamel", "params": {"mass": 1}}, "params.mass", "value_error"),
        ({"system": "appell-hamel", "params": {"rho": "2*3"}}, "params.rho", "float_type"),  # never evaluated
        ({"system": "appell-hamel", "initial": {"u3": 7}}, "initial.u3", "value_error"),
        (
            {
                "system": "appell-hamel",
                "initial": {
                    "theta": 0,
                    "phi": 0,
                    "x": 0,
                    "y": 0,
                    "z": 30,
                    "u1": 1,
                    "u2": 1,
                    "u3": 2,
                    "u4": 5,
                    "u5": -0.5,
                },
            },
            "initial",
            "inconsistent_state",
        ),
        ({"system": "appell-hamel", "gamma": [[-1, 0, 0]]}, "gamma", "value_error"),  # Γ is 2×2 here
        ({"system": "appell-hamel", "color": "red"}, "color", "extra_forbidden"),  # unknown field
    ],
)
def test_bad_input_gets_422_with_field_path_value_and_reason(client, body, field, kind):
    err = _error(client.post("/api/runs", json=body))
    assert err["field"] == field and err["loc"][0] == "body" and err["type"] == kind, err
    assert err["reason"] and err["allowed"], err
    top = field.split(".")[0]
    if top in body and not isinstance(body[top], dict):
        assert err["value"] == body[top]
    assert field in err["msg"]


def test_unknown_system_error_lists_the_systems(client):
    err = _error(client.post("/api/runs", json={"system": "pendulum"}))
    assert "appell-hamel" in err["allowed"] and "sliding-particle" in err["allowed"] and err["value"] == "pendulum"


def test_inconsistent_initial_state_says_which_constraint(client):
    full = {"theta": 0, "phi": 0, "x": 0, "y": 0, "z": 30, "u1": 1, "u2": 1, "u3": 2, "u4": 5, "u5": -0.5}
    err = _error(client.post("/api/runs", json={"system": "appell-hamel", "initial": full}))
    assert err["type"] == "inconsistent_state" and err["value"]["u3"] == 2
    assert "project_initial" in err["msg"] or "constraint" in err["msg"]


@pytest.mark.parametrize(
    "raw,field,shown",
    [
        (b'{"system": "appell-hamel", "dt": NaN}', "dt", "NaN"),
        (b'{"system": "appell-hamel", "t_final": Infinity}', "t_final", "Infinity"),
        (b'{"system": "appell-hamel", "params": {"rho": -Infinity}}', "params.rho", "-Infinity"),
        (b'{"system": "appell-hamel", "gamma": NaN}', "gamma", "NaN"),
    ],
)
def test_nan_and_infinity_in_json_get_422(client, raw, field, shown):
    r = client.post("/api/runs", content=raw, headers={"content-type": "application/json"})
    err = _error(r)
    assert err["field"].startswith(field) and err["value"] == shown, err


def test_hostile_bodies_get_4xx_in_the_error_shape_never_5xx(client):
    cases = [
        b"[" * 20000,
        b'{"system": "' + b"a" * 60000 + b'"}',
        b"not json",
        b"",
        b"null",
        b"[]",
        b'{"system": 1e999999}',
        b'{"params": {"rho": 1e308}}',
        b"\xff\xfe\x00",
        b'{"dt": 1e-320}',
        b'{"gamma": [[1e308, 1e308, 1e308], [0, 0, 0], [0, 0, 0]]}',
        b'{"every": 99999999999999999999999}',
        b'{"initial": {"__class__": 1}}',
        b'{"system": "appell-hamel", "system": "x"}',
    ]
    for raw in cases:
        r = client.post("/api/runs", content=raw, headers={"content-type": "application/json"})
        assert 400 <= r.status_code < 500, (raw[:30], r.status_code, r.text[:200])
        _error(r, r.status_code)
    long_value = _error(client.post("/api/runs", json={"system": "a" * 60000}))["value"]
    assert len(long_value) < 300  # echoed values are shortened
    _error(client.post("/api/runs", content=b"system=appell-hamel", headers={"content-type": "text/plain"}), 415)


def test_oversized_body_gets_413(client):
    big = {"system": "appell-hamel", "initial": {f"k{i}": 0.0 for i in range(10000)}}
    err = _error(client.post("/api/runs", json=big), 413)
    assert err["type"] == "too_large" and "65,536" in err["allowed"]


def test_oversized_streamed_body_without_length_gets_413(client):
    def chunks():
        yield b'{"system": "appell-hamel", "initial": {'
        for i in range(5000):
            yield f'"k{i}": 0.0, '.encode()
        yield b'"z": 1}}'

    r = client.post("/api/runs", content=chunks(), headers={"content-type": "application/json"})
    assert "content-length" not in r.request.headers
    assert _error(r, 413)["type"] == "too_large"


def test_unknown_run_and_route_get_404_wrong_method_405(client):
    assert _error(client.get("/api/runs/doesnotexist"), 404)["value"] == "doesnotexist"
    assert _error(client.get("/api/runs/doesnotexist.csv"), 404)["field"] == "run_id"
    _error(client.get("/api/nothing-here"), 404)
    r = client.delete("/api/runs")
    _error(r, 405)
    assert set(r.headers["allow"].split(", ")) == {"GET", "POST"}


# --------------------------------------------------------------------------- normal odd results
def test_singular_and_diverged_runs_are_normal_results(client):
    r = client.post("/api/runs", json={"system": "appell-hamel", "initial": {"u2": 0}, "switching": False})
    assert r.status_code == 201 and r.json()["summary"]["status"] == "singular"
    r = client.post("/api/runs", json={"system": "appell-hamel", "gamma": 1e6})
    assert r.status_code == 201
    doc = r.json()
    assert doc["summary"]["status"] == "drifted" and "past the run's bound" in doc["summary"]["message"]
    RunResult.model_validate(doc)  # every number finite, no nulls
    arrays = [doc["t"], doc["energy"], *doc["state"].values(), *doc["violation"].values()]
    assert all(isinstance(v, float) and math.isfinite(v) for a in arrays for v in a)


def test_diverged_run_summary_stays_valid_json_numbers(client):
    # Γ2 > 0 destabilizes the thread constraint; a library version reported the maximum
    # violation as inf, which JSON cannot carry (found by fuzzing): the document must still
    # conform to RunResult, whose maxima are numbers, never null
    r = client.post("/api/runs", json={"system": "appell-hamel", "gamma2": 10.0})
    assert r.status_code == 201
    summary = RunResult.model_validate_json(r.content).summary
    assert summary.status in ("diverged", "drifted")
    assert all(math.isfinite(v) for v in summary.max_abs_violation.values())
    assert math.isfinite(summary.max_abs_energy_drift)
    listing = client.get("/api/runs").json()["runs"][0]
    assert listing["summary"]["max_abs_violation"] == r.json()["summary"]["max_abs_violation"]
