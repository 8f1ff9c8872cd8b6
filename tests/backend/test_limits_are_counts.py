"""The limits that are counts are served as integers (issue 44: ``queue_limit`` was 64.0)."""


def test_service_limits_that_are_counts_are_integers(client):
    limits = client.get("/api/systems").json()["service_limits"]
    assert limits["queue_limit"] == 64 and isinstance(limits["queue_limit"], int)
    assert isinstance(limits["max_steps"], int) and isinstance(limits["max_wall_time_s"], float)
    schema = client.get("/openapi.json").json()["components"]["schemas"]["Catalog"]["properties"]
    assert {"type": "integer"} in schema["service_limits"]["additionalProperties"]["anyOf"]
