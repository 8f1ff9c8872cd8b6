"""Property-based fuzzing of the OpenAPI schema (schemathesis): no 5xx, responses conform."""

import warnings

import pytest

warnings.filterwarnings("ignore", message=".*httpx.*")
schemathesis = pytest.importorskip("schemathesis")
from hypothesis import HealthCheck, settings  # noqa: E402
from schemathesis.specs.openapi.checks import positive_data_acceptance  # noqa: E402

from backend import Settings, create_app  # noqa: E402
import tempfile, pathlib  # noqa: E402,E401

_APP = create_app(Settings(data_dir=pathlib.Path(tempfile.mkdtemp()), warm_kernels=False,
                           max_wall_time_s=0.5, max_steps=200_000))
schema = schemathesis.openapi.from_asgi("/openapi.json", _APP)


@schema.parametrize()
@settings(max_examples=30, deadline=None, suppress_health_check=list(HealthCheck))
def test_api_never_answers_5xx_and_conforms_to_its_schema(case):
    response = case.call()
    assert response.status_code < 500, response.text[:500]
    # schema-valid but semantically wrong settings (a model of the other system, an initial
    # state off the constraints, ...) are rightly refused with 422: not a failure here
    case.validate_response(response, excluded_checks=[positive_data_acceptance])
