"""Declared events (nmkane_core.run.events) and stability sweeps (nmkane_core.analysis.eigensweep), on the
Whipple bicycle and on a small system declared here."""

import json

import numpy as np
import pytest

from nmkane_core import simulate
from nmkane_core.analysis.eigensweep import crossings, sweep
from nmkane_core.run.events import _regula_falsi, stop_at_event
from nmkane_core.schema import RunResult
from nmkane_core.systems.whipple_bicycle import CAPSIZE_SPEED, WEAVE_SPEED


def _bike(speed, t_final=10.0, **initial):
    return simulate(
        {"system": "whipple-bicycle", "t_final": t_final, "every": 10, "initial": {"u6": -speed / 0.3, **initial}},
        progress=False,
    )


def test_a_crossing_is_located_to_round_off_and_the_stop_is_the_first_rising_one_asked():
    """The root finder of the event crossings (the Illinois method) and the choice of the stop:
    the earliest rising crossing of an event in the run's stop set; falling crossings and events
    outside it are recorded only."""
    root = _regula_falsi(lambda x: x * x - 2.0, 1.0, 2.0)
    assert root == pytest.approx(np.sqrt(2.0), abs=1e-12) and root * root - 2.0 >= 0.0  # at or past the zero
    assert _regula_falsi(lambda x: np.nan if x > 1.2 else x - 1.5, 1.0, 2.0) == 2.0  # not finite: the row's
    found = [
        {"name": "a", "t": 0.5, "direction": "falling", "row": 1},
        {"name": "b", "t": 1.0, "direction": "rising", "row": 2},
        {"name": "a", "t": 1.5, "direction": "rising", "row": 2},
    ]
    assert stop_at_event(found, frozenset({"a"}))["t"] == 1.5
    assert stop_at_event(found, frozenset({"a", "b"}))["name"] == "b"
    assert stop_at_event(found, frozenset()) is None


def test_bicycle_at_3_m_per_s_falls_and_the_run_stops_with_the_event():
    run = _bike(3.0, u4=0.5)
    assert run.status == "event"
    ev = run.summary["event"]
    assert ev["name"] == "handlebar_touches_ground" and 0.5 < ev["t"] < 10.0
    assert run.t[-1] == pytest.approx(ev["t"]) and run.summary["t_end"] == pytest.approx(ev["t"])
    assert np.all(np.isfinite(run.state["q4"])) and abs(run.state["q4"][-1]) > 0.8  # lying over
    doc = RunResult.model_validate_json(run.document().model_dump_json(by_alias=True))  # REST's schema
    assert doc.summary.status == "event" and doc.summary.event.name == ev["name"]
    assert "handlebar_touches_ground" in json.dumps(run.summary)


def test_bicycle_at_5_m_per_s_is_self_stable_no_event():
    run = _bike(5.0, u4=0.5)
    assert run.status == "ok" and run.summary.get("event") is None
    q4 = np.abs(run.state["q4"])
    assert q4.max() > 20 * q4[-50:].max()  # the perturbation dies out
    assert q4[-1] < 5e-3 and abs(run.state["u4"][-1]) < 5e-3


def test_bicycle_above_capsize_speed_leans_over_slowly():
    run = _bike(7.5, u4=0.5)
    q4 = np.abs(run.state["q4"])
    assert run.status == "ok"
    assert q4[-1] > q4[len(q4) // 2] > 0.01  # growing, slowly (no event within 10 s)


def test_stability_sweep_finds_the_benchmark_weave_and_capsize_speeds():
    rows = sweep("whipple-bicycle", np.linspace(3.0, 7.0, 9))
    found = {c["name"]: c for c in crossings("whipple-bicycle", rows)}
    assert set(found) == {"weave", "capsize"}
    assert found["weave"]["kind"] == "complex" and found["capsize"]["kind"] == "real"
    assert found["weave"]["value"] == pytest.approx(WEAVE_SPEED, rel=1e-8)
    assert found["capsize"]["value"] == pytest.approx(CAPSIZE_SPEED, rel=1e-8)
    assert found["weave"]["reference"] == WEAVE_SPEED
    five = next(r for r in rows if r["value"] == 5.0)
    assert all(re < 0 for re, _ in five["eigenvalues"])  # self-stable at 5 m/s


def test_stability_of_a_system_without_a_declaration_is_an_input_error():
    from nmkane_core.errors import InputError

    with pytest.raises(InputError, match="stability"):
        sweep("knife-edge", [1.0])


def test_cli_stability_prints_the_table_and_draws(tmp_path, capsys):
    from nmkane_core.cli import main

    out = tmp_path / "eig.png"
    assert main(["stability", "whipple-bicycle", "--over", "4:6.5:6", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "weave speed: 4.2923825" in text and "capsize speed: 6.024262" in text
    assert out.stat().st_size > 10_000


def test_a_user_system_declares_an_event():
    import sympy as sp

    from nmkane_core import MechanicalModel, System, plain_symbols, register, unregister

    def model():
        x, v = plain_symbols("x v")
        g = sp.Symbol("g", positive=True)
        return MechanicalModel(
            q=(x,),
            u=(v,),
            params=(g,),
            C=sp.eye(1),
            D=sp.zeros(1, 1),
            Q=sp.eye(1),
            P=sp.Matrix([-g]),
            energy=v**2 / 2 + g * x,
        )

    def events():
        x = sp.Symbol("x")
        return {"lands": -x}

    from nmkane_core import Parameter

    register(
        System(
            name="test-falling-ball",
            variants=model,
            parameters={"g": Parameter(9.81, 0, 100)},
            default_initial={"x": 1.0, "v": 0.0},
            default_dt=0.001,
            default_t_final=2.0,
            events=events,
        )
    )
    try:
        run = simulate({"system": "test-falling-ball", "every": 7}, progress=False)
        assert run.status == "event" and run.summary["event"]["name"] == "lands"
        assert run.summary["event"]["t"] == pytest.approx(np.sqrt(2 / 9.81), abs=1e-4)
        assert run.state["x"][-1] == pytest.approx(0.0, abs=1e-4)
    finally:
        unregister("test-falling-ball")


def test_the_catalogue_lists_the_stability_sweep_and_what_to_try():
    """GET /api/systems (the library's catalog) says what `nmkane stability` sweeps."""
    from nmkane_core.run.catalog import catalog

    systems = {s["name"]: s for s in catalog()["systems"]}
    st = systems["whipple-bicycle"]["stability"]
    assert st["over"] == "speed" and st["keep"] == ["q4", "q7", "u4", "u7"]
    assert st["reference"]["weave"] == 4.29238253634111
    assert systems["knife-edge"]["stability"] is None
    assert "5 m/s" in systems["whipple-bicycle"]["what_to_try"]
