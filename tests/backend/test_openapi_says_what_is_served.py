"""The OpenAPI document says what the service serves and refuses (issue 44, item 9).

``GET /api/sweeps/{id}.csv`` answers CSV and is documented so (it was documented as JSON);
a body the schema allows is not refused for a reason the schema could state: an empty system,
model or formulation name, or an empty parameter or state name, are refused by the schema
itself (``minLength``), in the one error shape, before any system is looked up.
"""

from __future__ import annotations

import pytest

ERROR_JSON = {"application/json": {"schema": {"$ref": "#/components/schemas/ErrorResponse"}}}


def test_sweep_csv_is_documented_as_text_csv_and_its_errors_as_the_error_shape(client):
    responses = client.get("/openapi.json").json()["paths"]["/api/sweeps/{sweep_id}.csv"]["get"]["responses"]
    assert list(responses["200"]["content"]) == ["text/csv"]
    assert responses["404"]["content"] == ERROR_JSON and responses["422"]["content"] == ERROR_JSON
    missing = client.get("/api/sweeps/nothing-here.csv")
    assert missing.status_code == 404 and missing.headers["content-type"] == "application/json"


def test_sweep_csv_answers_text_csv(client):
    created = client.post(
        "/api/sweeps", json={"settings": {"system": "sliding-particle", "t_final": 0.01}, "grid": ["gamma1=-1,-2"]}
    )
    assert created.status_code == 202, created.text
    csv = client.get(f"/api/sweeps/{created.json()['id']}.csv")
    assert csv.status_code == 200 and csv.headers["content-type"].startswith("text/csv")


@pytest.mark.parametrize("field", ["system", "model", "formulation"])
def test_an_empty_name_is_refused_by_the_schema_which_says_so(client, field):
    schema = client.get("/openapi.json").json()["components"]["schemas"]["RunSettings"]["properties"][field]
    assert {"type": "string", "maxLength": 64, "minLength": 1} in schema["anyOf"]
    r = client.post("/api/runs", json={field: "", "t_final": 0.01})
    assert r.status_code == 422
    [err] = r.json()["detail"]
    assert err["loc"] == ["body", field] and err["type"] == "string_too_short"
    assert err["allowed"] == "a string of at least 1 character"


@pytest.mark.parametrize("field", ["params", "initial"])
def test_an_empty_parameter_or_state_name_is_refused_by_the_schema_which_says_so(client, field):
    schema = client.get("/openapi.json").json()["components"]["schemas"]["RunSettings"]["properties"][field]
    assert schema["propertyNames"] == {"minLength": 1}
    r = client.post("/api/runs", json={field: {"": 1.0}, "t_final": 0.01})
    assert r.status_code == 422
    [err] = r.json()["detail"]
    assert err["loc"][:3] == ["body", field, ""] and err["type"] == "string_too_short"
