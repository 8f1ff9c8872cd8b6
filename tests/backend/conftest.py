"""The REST tests' service: a fresh store in a temporary folder, no kernel warm-up."""

import pytest
from fastapi.testclient import TestClient

from backend import Settings, create_app


@pytest.fixture()
def settings(tmp_path):
    return Settings(data_dir=tmp_path, warm_kernels=False)


@pytest.fixture()
def client(settings):
    with TestClient(base_url="http://localhost", app=create_app(settings)) as c:
        yield c
