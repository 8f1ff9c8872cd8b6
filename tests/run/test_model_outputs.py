"""A model's ``outputs`` ("extra reported quantities") reach the run: ``run.state``, its columns,
the CSV and the REST document (issue 45, item 1: they were computed and thrown away)."""

import numpy as np
import pytest

from nmkane_core import MechanicalModel, Parameter, System, plain_symbols, register, simulate
from nmkane_core.run.registry import unregister
from tests._helpers import require

NAME = "test-spring-outputs"


def _spring() -> MechanicalModel:
    import sympy as sp

    x, v = plain_symbols("x v")
    k = sp.Symbol("k", real=True)
    return MechanicalModel(
        name="spring",
        q=(x,),
        u=(v,),
        params=(k,),
        C=sp.eye(1),
        D=sp.zeros(1, 1),
        Q=sp.Matrix([[1]]),
        P=sp.Matrix([-k * x]),
        outputs={"energy2": (v**2 + k * x**2) / 2, "x_squared": x**2},
    )


@pytest.fixture(scope="module")
def system():
    registered = register(
        System(
            name=NAME,
            title="Spring with outputs (test)",
            variants=_spring,
            parameters={"k": Parameter(4.0, 0.0, 1e3, "N/m")},
            default_initial={"x": 1.0, "v": 0.0},
            default_dt=0.001,
            default_t_final=1.0,
        )
    )
    yield registered
    unregister(NAME)


def test_a_models_outputs_are_in_the_runs_state_columns_and_csv(system):
    run = simulate({"system": system.name}, progress=False)
    assert list(run.state) == ["x", "v", "energy2", "x_squared"]  # the state first, then the outputs
    x, v = run.state["x"], run.state["v"]
    np.testing.assert_allclose(run.state["energy2"], (v**2 + 4.0 * x**2) / 2, rtol=1e-14)
    np.testing.assert_allclose(run.state["x_squared"], x**2, rtol=1e-14)
    assert abs(run.state["energy2"] - 2.0).max() < 1e-9  # the spring's energy, kept by the run
    assert {"energy2", "x_squared"} <= set(run.columns())
    assert run.to_csv().splitlines()[0].split(",")[:5] == ["t", "x", "v", "energy2", "x_squared"]


def test_a_models_outputs_are_in_the_rest_document(system):
    require("fastapi")
    import tempfile

    from fastapi.testclient import TestClient

    from backend.app import create_app
    from backend.config import Settings

    with (
        tempfile.TemporaryDirectory() as tmp,
        TestClient(create_app(Settings(data_dir=tmp, warm_kernels=False)), base_url="http://localhost") as c,
    ):
        r = c.post("/api/runs", json={"system": system.name, "t_final": 0.1})
        assert r.status_code == 201, r.text
        doc = c.get(f"/api/runs/{r.json()['id']}").json()
        assert {"energy2", "x_squared"} <= set(doc["state"])


def test_the_pages_plot_chooser_offers_a_models_outputs(system):
    require("viser")
    from web.generic import _plot_controls

    options = {c.label: c.options for c in _plot_controls(system, "")}
    assert {"energy2", "x_squared"} <= set(options["Plot y ="]) and "x" in options["Plot y ="]
