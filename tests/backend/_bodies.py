"""The REST tests' shared request bodies, and the check of the one error shape."""

from backend.errors import ErrorResponse

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 20}
# Long because of its step count, not because of the machine's speed: 40 million steps (the
# library allows 50 million; the service's default cap is lifted for it by LONG_OK), which no
# machine integrates within the wall-time limits the tests below set (seconds): those runs
# always end as "timeout".  (The earlier 1.8 million steps ended "ok" within 1 s on a fast
# machine, and test_past_queue_limit_answers_503_with_retry_after failed there.)
LONG = {"system": "appell-hamel", "dt": 1e-5, "t_final": 400, "every": 40_000}
LONG_OK = {"max_steps": 40_000_000}


def error_of(r, status=422):
    assert r.status_code == status, r.text[:500]
    body = ErrorResponse.model_validate(r.json())  # the one error shape
    assert body.detail and all(e.msg for e in body.detail)
    return r.json()["detail"][0]
