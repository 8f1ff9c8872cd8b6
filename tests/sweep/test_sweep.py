"""nmkane sweep: specification parsing, executors (this process, local processes, a real Dask
LocalCluster) against direct ``simulate`` runs, resume after an interruption, bad input."""

import math

import numpy as np
import pytest

from nmkane_core.cli import main
from nmkane_core.errors import InputError
from nmkane_core.run.simulate import simulate
from nmkane_core.sweep import apply_point, parse_axis, read_rows, run_sweep, sweep_spec
from nmkane_core.sweep.executors import run_point
from tests._helpers import require

BASE = {"system": "sliding-particle", "t_final": 0.5, "dt": 0.01}
COMPARED = ("status", "max_abs_violation.surface", "max_abs_energy_drift", "final_energy_drift", "steps")


def _direct(point):
    s = simulate(apply_point(BASE, point), progress=False).summary
    return {
        "status": s["status"],
        "max_abs_violation.surface": s["max_abs_violation"]["surface"],
        "max_abs_energy_drift": s["max_abs_energy_drift"],
        "final_energy_drift": s["final_energy_drift"],
        "steps": s["steps"],
    }


def _check_rows_equal_direct(path, names, n):
    columns, rows = read_rows(path)
    assert columns[: len(names)] == names
    assert len(rows) == n
    keys = {tuple(r[k] for k in names) for r in rows}
    assert len(keys) == n  # each point once
    for r in rows:
        want = _direct({k: r[k] for k in names})
        assert {k: r[k] for k in COMPARED} == want  # exactly: floats round-trip through repr
        assert r["wall_time_s"] > 0
    return rows


# ---------------------------------------------------------------- parsing


def test_grid_list_log_and_lhs_parsing():
    a = parse_axis("gamma1=-40:-10:4")
    assert a.name == "gamma1" and a.values == (-40.0, -30.0, -20.0, -10.0)
    assert parse_axis("params.m=1,2.5,4").values == (1.0, 2.5, 4.0)
    assert parse_axis("integrator=rk4,kutta-merson").values == ("rk4", "kutta-merson")
    log = parse_axis("gamma2=-1:-1000:4", log=True)
    assert log.values[0] == -1.0 and log.values[-1] == -1000.0
    assert np.allclose(log.values, [-1, -10, -100, -1000])
    assert parse_axis("initial.x=0.5:0.5:1").values == (0.5,)
    spec = sweep_spec(grid=["gamma1=-20,-10"], sample=["gamma2=-200:-50", "params.m=1:2"], samples=5, seed=3)
    assert spec.names == ["gamma1", "gamma2", "params.m"] and len(spec) == 10
    pts = list(spec.points())
    assert len(pts) == 10
    lhs = spec.sample_points()
    for j, (lo, hi) in enumerate(spec.sample.values()):  # Latin hypercube: one point per stratum
        strata = np.floor((lhs[:, j] - lo) / (hi - lo) * 5).astype(int)
        assert sorted(strata) == [0, 1, 2, 3, 4]
    again = sweep_spec(sample=["gamma2=-200:-50", "params.m=1:2"], samples=5, seed=3).sample_points()
    assert np.array_equal(again, lhs)  # a seed reproduces the sample (resume)
    assert apply_point({"system": "x", "params": {"g": 1.0}}, {"params.m": 2.0, "gamma": -1.0}) == {
        "system": "x",
        "params": {"g": 1.0, "m": 2.0},
        "initial": {},
        "gamma": -1.0,
    }


@pytest.mark.parametrize(
    "kwargs, needle",
    [
        ({"grid": ["gamma=1:2"]}, "2 fields"),
        ({"grid": ["gamma"]}, "no '='"),
        ({"grid": ["colour=1,2"]}, "unknown name"),
        ({"grid": ["gamma=1,x"]}, "not a number"),
        ({"grid": ["gamma=1,1"]}, "repeats"),
        ({"grid": ["gamma=0:1:0"]}, "NUM"),
        ({"log_grid": ["gamma=-1:1:3"]}, "one sign"),
        ({"log_grid": ["gamma=0:10:3"]}, "nonzero"),
        ({"sample": ["gamma=1:0"]}, "LOW is not below HIGH"),
        ({"sample": ["gamma=-1:0"]}, "--samples"),
        ({"grid": ["gamma=1,2"], "samples": 3}, "nothing to sample"),
        ({}, "nothing varies"),
        ({"grid": ["gamma=1,2", "gamma=3,4"]}, "varied twice"),
    ],
)
def test_bad_specifications_are_input_errors(kwargs, needle):
    with pytest.raises(InputError) as e:
        sweep_spec(**kwargs)
    assert needle in str(e.value)


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["--grid", "gamma1=-40:-10"], "--grid"),
        (["--grid", "gamma1=-1e9,-20"], "--grid gamma1: got -1000000000.0"),  # refused by the system
        (["--grid", "params.l0=-1,1"], "--grid params.l0"),
        (["--grid", "gamma1=-20,-10", "--out", "x.txt"], "--out"),
        (["--grid", "gamma1=-20,-10", "--plot", "x.gif"], "--plot"),
        (["--grid", "gamma1=-20,-10", "--dask", "nowhere"], "--dask"),
        (["--grid", "gamma1=-20,-10", "--grid", "gamma2=-1,-2", "--grid", "dt=0.01,0.02", "--plot", "a.png"], "--plot"),
    ],
)
def test_bad_sweep_commands_print_one_line_and_exit_2(argv, needle, tmp_path, capsys):
    if "--out" not in argv:
        argv = [*argv, "--out", str(tmp_path / "s.csv")]
    code = main(["sweep", "sliding-particle", "--t-final", "0.1", "--no-progress", *argv])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and needle in err, err


def test_parquet_needs_pyarrow(tmp_path, capsys, monkeypatch):
    import sys

    for name in ("pyarrow", "pyarrow.parquet"):  # as if not installed (None in sys.modules: ImportError)
        monkeypatch.setitem(sys.modules, name, None)
    code = main(["sweep", "sliding-particle", "--grid", "gamma1=-1,-2", "--out", str(tmp_path / "s.parquet")])
    err = capsys.readouterr().err
    assert code == 2 and "pyarrow" in err and len(err.strip().splitlines()) == 1


def test_parquet_rows_equal_the_csv_rows(tmp_path, capsys):
    require("pyarrow")
    spec = sweep_spec(grid=["integrator=rk4,kutta-merson"], log_grid=["gamma2=-10:-1000:3"])
    csv_out, pq_out = str(tmp_path / "s.csv"), str(tmp_path / "s.parquet")
    run_sweep(BASE, spec, csv_out, workers=1, progress=False)
    argv = "sweep sliding-particle --t-final 0.5 --dt 0.01 --grid integrator=rk4,kutta-merson"
    argv += " --log-grid gamma2=-10:-1000:3 --workers 1 --no-progress --out"
    code = main([*argv.split(), pq_out])
    assert code == 0, capsys.readouterr().err
    c_cols, c_rows = read_rows(csv_out)
    p_cols, p_rows = read_rows(pq_out)
    assert p_cols == c_cols and len(p_rows) == len(c_rows) == 6

    def same(r):  # wall time differs from run to run; everything else is equal, floats exactly
        return {k: v for k, v in r.items() if k != "wall_time_s"}

    key = ("integrator", "gamma2")
    assert sorted(map(same, p_rows), key=lambda r: tuple(r[k] for k in key)) == sorted(
        map(same, c_rows), key=lambda r: tuple(r[k] for k in key)
    )
    import pyarrow.parquet as pq

    schema = pq.read_schema(pq_out)
    assert str(schema.field("integrator").type) == "string" and str(schema.field("steps").type) == "int64"
    assert str(schema.field("gamma2").type) == "double"
    _check_rows_equal_direct(pq_out, ["integrator", "gamma2"], 6)


def test_parquet_resume_after_an_interruption(tmp_path):
    require("pyarrow")
    spec = sweep_spec(grid=["gamma1=-40:-10:4", "gamma2=-100,-10"])
    out = str(tmp_path / "s.parquet")
    seen = []

    def stop_after_three(rows):
        seen.extend(rows)
        if len(seen) >= 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(BASE, spec, out, workers=1, progress=False, on_rows=stop_after_three)
    _, partial = read_rows(out)  # the rows written before the interruption are in the file
    assert len(partial) == 3
    res = run_sweep(BASE, spec, out, workers=1, progress=False)
    assert res.skipped == 3 and res.ran == 5
    rows = _check_rows_equal_direct(out, ["gamma1", "gamma2"], 8)
    assert rows[:3] == partial  # the old rows first, unchanged
    again = run_sweep(BASE, spec, out, workers=1, progress=False)
    assert again.ran == 0 and again.skipped == 8
    _, rows_again = read_rows(out)
    assert rows_again == rows


# ---------------------------------------------------------------- executors


def test_local_processes_equal_direct_runs(tmp_path):
    spec = sweep_spec(grid=["gamma1=-40,-20"], log_grid=["gamma2=-10:-1000:3"])
    out = str(tmp_path / "s.csv")
    res = run_sweep(BASE, spec, out, workers=2, progress=False)
    assert res.executor == "processes" and res.ran == 6 and res.statuses == {"ok": 6}
    _check_rows_equal_direct(out, ["gamma1", "gamma2"], 6)


def test_dask_local_cluster_equals_direct_runs(tmp_path):
    require("distributed")
    from nmkane_core.sweep.executors import DaskExecutor

    spec = sweep_spec(grid=["integrator=rk4,kutta-merson"], sample=["params.m=0.5:2"], samples=2, seed=7)
    out = str(tmp_path / "s.csv")
    with DaskExecutor("local:2", warm=({**BASE, "integrator": "rk4"}, {**BASE, "integrator": "kutta-merson"})) as ex:
        assert ex.workers == 2
        pids = set(ex.client.run(__import__("os").getpid).values())
        assert len(pids) == 2  # two worker processes
        res = run_sweep(BASE, spec, out, executor=ex, progress=False)
        # a second sweep on the same client, with other base settings (the scattered base of
        # the first must not collide with this one's: it once did, key by key)
        out2 = str(tmp_path / "s2.csv")
        res2 = run_sweep(
            {**BASE, "t_final": 0.3}, sweep_spec(grid=["gamma1=-20,-10"]), out2, executor=ex, progress=False
        )
        assert res2.ran == 2 and res2.statuses == {"ok": 2}
    assert res.executor == "dask" and res.ran == 4
    rows = _check_rows_equal_direct(out, ["integrator", "params.m"], 4)
    assert {r["integrator"] for r in rows} == {"rk4", "kutta-merson"}
    _, rows2 = read_rows(out2)
    for r in rows2:
        want = simulate({**BASE, "t_final": 0.3, "gamma1": r["gamma1"]}, progress=False).summary
        assert r["max_abs_violation.surface"] == want["max_abs_violation"]["surface"] and r["steps"] == 30


def test_resume_after_an_interruption(tmp_path):
    spec = sweep_spec(grid=["gamma1=-40:-10:4", "gamma2=-100,-10"])
    out = str(tmp_path / "s.csv")
    seen = []

    def stop_after_three(rows):
        seen.extend(rows)
        if len(seen) >= 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run_sweep(BASE, spec, out, workers=1, progress=False, on_rows=stop_after_three)
    _, partial = read_rows(out)
    assert len(partial) == 3
    with open(out, "a") as f:  # a line cut off by the interruption
        f.write("-10.0,-100.0,ok,1e-")
    res = run_sweep(BASE, spec, out, workers=1, progress=False)
    assert res.skipped == 3 and res.ran == 5
    rows = _check_rows_equal_direct(out, ["gamma1", "gamma2"], 8)
    assert [r["gamma1"] for r in rows[:3]] == [r["gamma1"] for r in partial]
    again = run_sweep(BASE, spec, out, workers=1, progress=False)  # complete: nothing to do
    assert again.ran == 0 and again.skipped == 8


def test_resume_refuses_another_sweeps_file(tmp_path):
    out = str(tmp_path / "s.csv")
    run_sweep(BASE, sweep_spec(grid=["gamma1=-20"]), out, workers=1, progress=False)
    with pytest.raises(InputError, match="other columns"):
        run_sweep(BASE, sweep_spec(grid=["gamma2=-20"]), out, workers=1, progress=False)


def test_sweep_command_writes_rows_and_plot(tmp_path, capsys):
    out, png = tmp_path / "s.csv", tmp_path / "s.png"
    code = main(
        [
            "sweep",
            "sliding-particle",
            "--t-final",
            "0.3",
            "--grid",
            "gamma1=-30,-10",
            "--grid",
            "gamma2=-100,-10",
            "--workers",
            "1",
            "--no-progress",
            "--out",
            str(out),
            "--plot",
            str(png),
        ]
    )
    assert code == 0, capsys.readouterr().err
    assert "4 runs (0 already" in capsys.readouterr().out
    _, rows = read_rows(str(out))
    assert len(rows) == 4 and all(math.isfinite(r["max_abs_violation.surface"]) for r in rows)
    assert png.stat().st_size > 1000


def test_a_refused_point_is_a_row_not_a_crash():
    row = run_point(BASE, {"params.m": -1.0})
    assert row["status"] == "invalid" and "params.m" in row["message"] and row["params.m"] == -1.0


# ---------------------------------------------------------------- tune


def test_stability_interval_from_the_tableau():
    from nmkane_core.integrate.methods import KUTTA_MERSON, RK4
    from nmkane_core.sweep.tune import real_stability_interval, stability_polynomial, stable_gains

    assert np.allclose(stability_polynomial(RK4), [1, 1, 1 / 2, 1 / 6, 1 / 24])  # e^z to order 4
    assert np.allclose(stability_polynomial(KUTTA_MERSON), [1, 1, 1 / 2, 1 / 6, 1 / 24, 1 / 144])
    x = real_stability_interval(RK4)
    assert x == pytest.approx(-2.785293563405282, abs=1e-9)  # Hairer & Wanner II, Table IV.2.1
    R = np.polynomial.Polynomial([1, 1, 1 / 2, 1 / 6, 1 / 24])
    assert abs(R(x)) == pytest.approx(1) and abs(R(x - 1e-3)) > 1 and all(abs(R(np.linspace(x, 0, 500))) <= 1 + 1e-12)
    km = real_stability_interval(KUTTA_MERSON)
    assert -3.6 < km < -3.5
    dt = 0.01
    assert stable_gains(RK4, dt, G=x / dt * 0.999) and not stable_gains(RK4, dt, G=x / dt * 1.01)
    assert stable_gains(KUTTA_MERSON, dt, G1=-20, G2=-100)  # the paper's Γ1, Γ2 at dt = 0.01
    assert not stable_gains(KUTTA_MERSON, dt, G1=-20, G2=100)  # a positive real root


def test_tune_picks_the_smallest_violation_among_qualifying_gains():
    from nmkane_core.sweep.tune import tune

    base = {"system": "sliding-particle", "t_final": 1.0, "dt": 0.02, "gamma1": -20.0, "gamma2": -100.0}
    res = tune(base, points=3, energy_factor=1e6)
    cands = res.stages["holonomic"]
    assert res.outside["holonomic"] + len(cands) == 9
    best = res.chosen["holonomic"]
    assert best.feasible and best.violation == min(c.violation for c in cands if c.feasible)
    assert res.gains == best.gains
    direct = simulate({**base, **best.gains}, progress=False).summary
    assert direct["max_abs_violation"]["surface"] == best.violation
    assert res.given["holonomic"].gains == {"gamma1": -20.0, "gamma2": -100.0}


def test_tune_refuses_adaptive_integrators(capsys):
    code = main(["tune", "sliding-particle", "--integrator", "rk45", "--t-final", "0.1", "--workers", "1"])
    err = capsys.readouterr().err
    assert code == 2 and "fixed-step" in err and len(err.strip().splitlines()) == 1


# ---------------------------------------------------------------- REST


@pytest.fixture()
def api(tmp_path):
    require("fastapi")
    from fastapi.testclient import TestClient

    from backend.app import create_app
    from backend.config import Settings

    with TestClient(
        create_app(Settings(data_dir=tmp_path, warm_kernels=False, max_concurrent_runs=2)), base_url="http://localhost"
    ) as c:
        yield c


def _wait(api, sweep_id, timeout=60.0):
    import time

    t0 = time.time()
    while time.time() - t0 < timeout:
        r = api.get(f"/api/sweeps/{sweep_id}")
        assert r.status_code == 200
        if r.json()["status"] in ("done", "failed"):
            return r.json()
        time.sleep(0.05)
    raise AssertionError("sweep did not finish")


def test_rest_sweep_runs_and_serves_rows_and_csv(api):
    body = {
        "settings": {"system": "sliding-particle", "t_final": 0.5, "dt": 0.01},
        "grid": ["gamma1=-40,-20"],
        "log_grid": ["gamma2=-10:-1000:3"],
    }
    r = api.post("/api/sweeps", json=body)
    assert r.status_code == 202, r.text
    sid = r.json()["id"]
    assert r.json()["total"] == 6 and r.headers["location"] == f"/api/sweeps/{sid}"
    state = _wait(api, sid)
    assert state["status"] == "done" and state["done"] == 6 and len(state["rows"]) == 6, state
    for row in state["rows"]:
        want = _direct({"gamma1": row["gamma1"], "gamma2": row["gamma2"]})
        assert {k: row[k] for k in COMPARED} == want
    csv_text = api.get(f"/api/sweeps/{sid}.csv").text
    lines = csv_text.strip().splitlines()
    assert lines[0].startswith("gamma1,gamma2,status,max_abs_violation.surface") and len(lines) == 7
    assert api.get("/api/sweeps/nope").status_code == 404


@pytest.mark.parametrize(
    "body, field, needle",
    [
        ({"grid": ["gamma1=1:2"]}, "grid", "2 fields"),
        ({"grid": ["gamma1=-1e9,-1"]}, "grid", "gamma1"),
        ({"grid": ["gamma1=-1:-2:20000"]}, "grid", "at most 10,000 runs"),
        (
            {"grid": ["dt=1e-4,0.01"], "settings": {"system": "sliding-particle", "t_final": 500, "every": 100}},
            "grid",
            "max_steps",
        ),
        ({}, "grid", "nothing varies"),
        ({"grid": ["gamma1=-1,-2"], "settings": {"system": "nope"}}, "settings", "nope"),
    ],
)
def test_rest_bad_sweeps_are_422(api, body, field, needle):
    body = {"settings": {"system": "sliding-particle", "t_final": 0.2}, **body}
    r = api.post("/api/sweeps", json=body)
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"][1] == field and needle in detail["msg"], detail


def test_bench_sweep_rows_measure_and_compare_rows(monkeypatch):
    """The bench's sweep rows on a small grid: every executor's rows equal the one-core rows,
    and the streaming-memory probe measures a real ``nmkane sweep`` process."""
    require("distributed")
    import nmkane_core.bench.sweep as sb

    monkeypatch.setattr(sb, "GRID", ["gamma1=-40,-5", "gamma2=-400,-25"])
    monkeypatch.setattr(sb, "TINY_GRID", ["gamma1=-40:-1:4", "gamma2=-400:-10:2"])
    got = []

    def add(workload, wall, evals=None, target=None, ok=None, note=""):
        got.append((workload, wall, target, ok, note))

    sb.sweep_rows(add, quick=True)
    names = [a[0] for a in got]
    assert any("one core" in n for n in names) and any("local executor" in n for n in names)
    assert any("Dask LocalCluster" in n for n in names) and any("Dask overhead" in n for n in names)
    for a in got:
        assert a[1] > 0 and "DIFFERENT" not in a[-1]
        if "executor" in a[0] or "LocalCluster" in a[0]:
            assert "rows equal" in a[-1]
    mb, wall = sb._sweep_peak_rss(6, 1)
    assert 10 < mb < 4000 and wall > 0
