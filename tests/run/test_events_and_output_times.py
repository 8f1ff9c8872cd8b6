"""Events that record their crossings, located to the integrator's accuracy, and go on unless
asked to stop; output at asked times (issue 45, item 3).  A pendulum of amplitude 1 rad has
exact crossing times: it passes the bottom at T/4, 3T/4, … and turns at T/2, T, …, with
T = 4 K(sin²(1/2)) / √g."""

import math

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipk

from nmkane_core import MechanicalModel, Parameter, System, plain_symbols, register, simulate
from nmkane_core.errors import InputError

NAME = "test-event-pendulum"
G = 9.81
PERIOD = 4 * ellipk(math.sin(0.5) ** 2) / math.sqrt(G)


def _model():
    x, v = plain_symbols("x v")
    g = sp.Symbol("g", positive=True)
    return MechanicalModel(
        q=(x,), u=(v,), params=(g,), C=sp.eye(1), D=sp.zeros(1, 1), Q=sp.eye(1),
        P=sp.Matrix([-g * sp.sin(x)]), energy=v**2 / 2 - g * sp.cos(x),
    )  # fmt: skip


def _events():
    x, v = sp.symbols("x v")
    return {"passes_bottom": x, "turns": -v}


@pytest.fixture(scope="module", autouse=True)
def pendulum():
    register(
        System(
            name=NAME,
            variants=_model,
            parameters={"g": Parameter(G, 0.1, 100.0, "m/s²", "gravity over length")},
            default_initial={"x": -1.0, "v": 0.0},
            default_dt=0.01,
            default_t_final=10.0,
            events=_events,
            stop_events=(),  # recorded, the run goes on
        )
    )


def test_every_crossing_is_recorded_to_the_integrators_accuracy_and_the_run_goes_on():
    """dt = 0.01 with every 10th row kept: rows 0.1 s apart, the crossings found within 1e-8 s
    (measured 4.5e-10; linear interpolation between the rows is off by ~1e-3 s)."""
    run = simulate({"system": NAME, "every": 10}, progress=False)
    assert run.status == "ok" and run.t[-1] == pytest.approx(10.0)
    bottom = [c["t"] for c in run.summary["crossings"] if c["name"] == "passes_bottom"]
    turns = [c for c in run.summary["crossings"] if c["name"] == "turns"]
    want = PERIOD / 4 + PERIOD / 2 * np.arange(len(bottom))
    assert len(bottom) == int((10.0 - PERIOD / 4) // (PERIOD / 2)) + 1
    assert np.abs(np.array(bottom) - want).max() < 1e-8
    # -v is 0 at rest at the start (≥ 0: fired), and falls below at once as the pendulum swings
    assert [c["direction"] for c in turns[:4]] == ["rising", "falling", "rising", "falling"]
    assert turns[0]["t"] == 0.0 and turns[1]["t"] < 1e-6
    assert abs(turns[2]["t"] - PERIOD / 2) < 1e-8 and abs(turns[3]["t"] - PERIOD) < 1e-8
    rows = np.flatnonzero(np.diff(np.sign(run.state["x"])) != 0)[0]
    linear = run.t[rows] - run.state["x"][rows] * (run.t[rows + 1] - run.t[rows]) / np.diff(run.state["x"])[rows]
    assert abs(linear - PERIOD / 4) > 1e2 * abs(bottom[0] - PERIOD / 4)  # what the rows alone would give


def test_an_event_asked_to_stop_ends_the_run_at_the_located_state():
    run = simulate({"system": NAME, "every": 10, "stop_at": ["passes_bottom"]}, progress=False)
    assert run.status == "event" and run.summary["event"]["name"] == "passes_bottom"
    assert run.summary["event"]["t"] == pytest.approx(PERIOD / 4, abs=1e-8) == run.t[-1] == run.summary["t_end"]
    assert abs(run.state["x"][-1]) < 1e-8 and run.state["v"][-1] == pytest.approx(math.sqrt(2 * G * (1 - math.cos(1))))
    assert [c["name"] for c in run.summary["crossings"]] == ["turns", "turns", "passes_bottom"]  # up to the stop


def test_output_times_give_the_state_there_to_the_integrators_accuracy():
    times = [0.0, 0.25, PERIOD / 4, 1.0, 2.345, 10.0]
    run = simulate({"system": NAME, "output_times": times}, progress=False)
    assert run.status == "ok" and run.t.tolist() == times and run.summary["t_end"] == 10.0
    assert abs(run.state["x"][2]) < 1e-8  # the bottom, exactly when asked
    fine = simulate({"system": NAME, "every": 1}, progress=False)  # the same steps, every row kept
    on_grid = [k for k, t in enumerate(times) if abs(t * 100 - round(t * 100)) < 1e-9]
    for k in on_grid:  # a time on the run's grid: the run's own row, bit for bit
        j = int(np.argmin(np.abs(fine.t - times[k])))
        assert run.state["x"][k] == fine.state["x"][j] and run.state["v"][k] == fine.state["v"][j]
    ref = simulate({"system": NAME, "dt": 1e-4, "output_times": times}, progress=False)
    err = np.abs(run.state["x"] - ref.state["x"])
    assert err.max() < 5e-8  # the run's global error (2.2e-8 at 10 s)
    assert err[2] < 1e-8 and err[4] < 1e-8  # off the grid too (linear interpolation: ~1e-4)
    E = run.energy
    assert np.abs(E - E[0]).max() < 1e-8 and set(run.violation) == set()


@pytest.mark.parametrize(
    "settings, field",
    [
        ({"output_times": [0.0, 2.0, 1.0]}, "output_times[2]"),
        ({"output_times": [0.0, 11.0]}, "output_times[1]"),
        ({"stop_at": ["lands"]}, "stop_at"),
    ],
)
def test_bad_output_times_and_unknown_events_are_refused_naming_the_field(settings, field):
    with pytest.raises(InputError) as e:
        simulate({"system": NAME, **settings}, progress=False)
    assert e.value.field == field


def test_the_rest_document_and_the_cli_carry_the_crossings(tmp_path):
    from fastapi.testclient import TestClient

    from backend.app import create_app
    from backend.config import Settings
    from nmkane_core.cli.run_cmd import format_summary

    app = create_app(Settings(data_dir=tmp_path, warm_kernels=False))
    with TestClient(app, base_url="http://localhost") as client:
        r = client.post("/api/runs", json={"system": NAME, "output_times": [0.0, 1.0, 2.0], "stop_at": []})
        assert r.status_code == 201, r.text
        doc = r.json()
    assert doc["t"] == [0.0, 1.0, 2.0] and doc["summary"]["status"] == "ok"
    bottom = [c for c in doc["summary"]["crossings"] if c["name"] == "passes_bottom"]
    assert bottom[0]["t"] == pytest.approx(PERIOD / 4, abs=1e-8) and bottom[0]["direction"] == "rising"
    run = simulate({"system": NAME, "t_final": 2.0}, progress=False)
    text = format_summary(run)
    assert "events   turns rising at 0 s, turns falling at " in text and "passes_bottom rising at 0.534784 s" in text
