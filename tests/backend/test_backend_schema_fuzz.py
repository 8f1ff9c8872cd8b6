"""Property-based fuzzing of the OpenAPI schema (schemathesis): no 5xx, responses conform.

Each operation gets schema-valid and schema-violating requests (bounded: the whole file
runs in well under a minute); every response must be a non-5xx that matches the
documented status codes, content types, headers and bodies (``RunResult`` for runs,
``ErrorResponse`` for errors).  The stateful test follows the OpenAPI links from
``POST /api/runs`` to ``GET /api/runs/{id}`` and its CSV, so stored runs are fetched
and checked too.
"""

import pytest

from tests._helpers import require

schemathesis = require("schemathesis")
from fastapi.testclient import TestClient
from hypothesis import HealthCheck, settings
from schemathesis.specs.openapi.checks import positive_data_acceptance

from backend import Settings, create_app
from nmkane_core.run.registry import system_names

# Schema-valid but semantically wrong settings (a model of the other system, an initial
# state off the constraints, an unknown parameter name...) are rightly refused with 422
# by the library's checks: that is not a failure of the API.
EXCLUDED = [positive_data_acceptance]
FUZZ = settings(max_examples=25, deadline=None, suppress_health_check=list(HealthCheck))


# small limits keep fuzzed runs short (a few ms each). The app is built at import, for
# parametrize, from its OpenAPI document alone: schemathesis' from_asgi would fetch it through
# a test client that runs the app's whole lifespan at import, in each worker (the service
# started, warmed, and stopped with a warm-up thread still compiling in the background, whose
# lines then landed in other tests' output). The database is opened only when the service
# starts, in the fixture below, so the path is set there, in pytest's temporary directory.
_SETTINGS = Settings(
    data_dir="unused",
    warm_kernels=False,
    max_wall_time_s=0.2,
    max_steps=100_000,
    max_rows=5_000,
    # every fuzzed sweep admitted (the admission's 503 is tested in test_sweep_admission.py) and
    # kept small: at most 20 runs of at most 0.2 s each
    max_sweeps=1_000_000,
    max_sweep_runs=20,
    allowed_hosts=("testserver",),
)  # the ASGI test client's host name
_APP = create_app(_SETTINGS)
schema = schemathesis.openapi.from_dict(_APP.openapi())
schema.app, schema.location = _APP, "/openapi.json"  # what from_asgi sets: requests go to the app


@pytest.fixture(scope="module", autouse=True)
def _service(tmp_path_factory):
    """The service, with every loop a fuzzed request can reach loaded first: on an empty kernel
    cache a first request compiles for ~12 s (a first projected one ~17 s), past schemathesis'
    10 s read timeout. A fuzzed ``system`` is a random string or null (the catalogue's first
    system): only that system's loops are reachable, not the IFToMM benchmarks' minutes of them.
    ``GET /api/systems`` derives every registered system once: it is asked once here."""
    _SETTINGS.db_path = tmp_path_factory.mktemp("fuzz") / "runs.sqlite3"
    with TestClient(_APP) as client:  # runs the lifespan: the service starts and stops
        assert client.get("/api/systems").status_code == 200
        svc = _APP.state.service
        default = system_names()[0]
        first, later = svc.warm_steps()
        svc.warm(None, [step for step in first + later if step[1]["system"] == default])
        yield


@schema.parametrize()
@FUZZ
def test_api_never_answers_5xx_and_conforms_to_its_schema(case):
    response = case.call()
    assert response.status_code < 500, response.text[:500]
    case.validate_response(response, excluded_checks=EXCLUDED)


def test_stateful_post_then_fetch_conforms():
    # DELETE is left out of the sequences: a run deleted and then fetched is rightly 404, which the
    # state machine's "created resource not found" check would report (DELETE: test_hardening_api.py)
    base = schema.exclude(method="DELETE").as_state_machine()

    class Machine(base):
        def validate_response(self, response, case, additional_checks=None, **kwargs):
            assert response.status_code < 500, response.text[:500]
            case.validate_response(
                response,
                additional_checks=additional_checks,
                excluded_checks=EXCLUDED,
                transport_kwargs=kwargs or None,
                recorder=self.recorder,
            )

    Machine.run(
        settings=settings(
            max_examples=15, stateful_step_count=4, deadline=None, suppress_health_check=list(HealthCheck)
        )
    )
