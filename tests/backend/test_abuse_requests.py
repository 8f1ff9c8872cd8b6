"""The service under abuse (issue 44): a request's cost is bounded before the work, and what is
out of range answers 422 in the one error shape, naming the field — never 500.

* ``POST /api/sweeps`` with a grid of 10⁷ points (113 bytes) answered its 422 after seconds of
  CPU and ~0.9 GB (the values were made before the run count was checked);
* a ``seed`` ≥ 2⁶⁴ was a 500 (the store's JSON has 64-bit integers), ``seed: -1`` a 202 and
  then a failed sweep;
* ``GET /api/sweeps/ID?offset=9223372036854775808`` was a 500 (SQLite's OFFSET is 64-bit).
"""

import time
import tracemalloc

import pytest

from nmkane_core.sweep import spec as spec_module
from nmkane_core.sweep.spec import SEED_MAX

GRID_10M = {"grid": ["gamma1=0.001:0.002:10000000"]}  # the 113-byte request
SMALL = {"settings": {"system": "sliding-particle", "t_final": 0.1}, "sample": ["gamma2=-2:-1"], "samples": 2}


def _post_measured(client, body) -> tuple:
    """The answer to ``POST /api/sweeps``, its wall time (s) and the peak memory Python
    allocated meanwhile (bytes, every thread: the route runs in the thread pool)."""
    tracemalloc.start()
    try:
        t0 = time.perf_counter()
        r = client.post("/api/sweeps", json=body)
        wall = time.perf_counter() - t0
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return r, wall, peak


def test_a_ten_million_point_grid_is_refused_before_any_value_is_made(client, made):
    client.get("/api/health")  # the app started: what follows is the request's own cost
    r, wall, peak = _post_measured(client, GRID_10M)
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "grid"] and err["value"] == "10,000,000 runs"
    assert err["allowed"] == "at most 10,000 runs per sweep" and "gamma1 10,000,000" in err["reason"]
    assert made == []  # no axis made: counted from the text
    assert peak < 5_000_000, f"{peak:,} bytes"  # was ~800 MB of floats (a tuple and a set)
    assert wall < 1.0, f"{wall:.3f} s"  # generous: measured 3 ms (was 4.4 s here, 80 s in the issue)


def test_sixteen_axes_of_ten_million_each_are_refused_at_once(client, made):
    body = {
        "grid": [f"params.p{i}=0:1:10000000" for i in range(8)],
        "log_grid": [f"initial.q{i}=1:2:10000000" for i in range(8)],
    }
    r, wall, peak = _post_measured(client, body)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["value"] == "about 10^112 runs"
    assert made == [] and peak < 5_000_000 and wall < 1.0


@pytest.mark.parametrize("seed", [-1, SEED_MAX + 1, 2**64])
def test_a_seed_out_of_range_answers_422_naming_seed(client, seed):
    r = client.post("/api/sweeps", json={**SMALL, "seed": seed})
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["body", "seed"] and err["field"] == "seed" and err["value"] == seed
    assert err["allowed"] in ("a number ≥ 0", f"a number ≤ {SEED_MAX}") and err["msg"].startswith("seed: got ")
    assert client.get("/api/health").status_code == 200  # the same client goes on


@pytest.mark.parametrize(
    "params, field",
    [({"offset": 2**63}, "offset"), ({"offset": -1}, "offset"), ({"limit": 2**63}, "limit"), ({"limit": 0}, "limit")],
)
def test_an_offset_or_limit_out_of_range_answers_422_not_500(client, params, field):
    r = client.get("/api/sweeps/no-such-sweep", params=params)
    assert r.status_code == 422, r.text
    (err,) = r.json()["detail"]
    assert err["loc"] == ["query", field] and err["allowed"].startswith("a number ")


def test_openapi_states_the_ranges_of_seed_samples_and_offset(client):
    doc = client.get("/openapi.json").json()
    props = doc["components"]["schemas"]["SweepRequest"]["properties"]
    assert (props["seed"]["minimum"], props["seed"]["maximum"]) == (0, SEED_MAX)
    assert props["samples"]["anyOf"][0]["maximum"] == spec_module.MAX_POINTS
    query = {p["name"]: p["schema"] for p in doc["paths"]["/api/sweeps/{sweep_id}"]["get"]["parameters"]}
    assert query["offset"]["maximum"] == 2**62 and query["limit"]["maximum"] == 10_000
