"""Issue 16, the library: strict settings, every violated limit in one message, hints that are
accepted, finite results after an overflow, switch targets loaded before the clock starts,
a progress bar on a terminal that reports no size, and ``nmkane bench``'s exit status."""

import math
import os
import pty
import select
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from nmkane_core.errors import InputError
from nmkane_core.run.plan import min_every, output_rows, resolve, validate_settings
from nmkane_core.run.simulate import simulate
from nmkane_core.schema import LIMITS

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


@pytest.mark.parametrize("settings", ["appell-hamel", ["system", "appell-hamel"], 3, None])
def test_settings_that_are_not_a_mapping_are_an_input_error_naming_settings(settings):
    with pytest.raises(InputError) as e:
        simulate(settings, progress=False)
    assert e.value.field == "settings" and "mapping" in e.value.allowed


@pytest.mark.parametrize(
    "settings,field",
    [
        ({"dt": True}, "dt"),
        ({"dt": "0.01"}, "dt"),
        ({"every": 2.0}, "every"),
        ({"every": True}, "every"),
        ({"params": {"rho": "4"}}, "params.rho"),
        ({"switching": 1}, "switching"),
        ({"t_final": "20"}, "t_final"),
    ],
)
def test_library_settings_are_as_strict_as_rest(settings, field):
    with pytest.raises(InputError) as e:
        resolve(settings)
    assert e.value.field == field, e.value


def test_numpy_numbers_and_tuples_are_still_accepted():
    plan = resolve(
        {
            "dt": np.float64(0.01),
            "every": np.int64(2),
            "t_final": 1,
            "gamma": np.diag([-1.0, -2]),
            "params": {"rho": np.float32(4.0)},
            "initial": {"u1": np.float64(0.5)},
        }
    )
    assert plan.dt == 0.01 and plan.every == 2 and plan.G[1, 1] == -2 and plan.params["rho"] == 4.0
    assert resolve({"gamma": ((-1.0, 0), (0, -1))}).G[1, 1] == -1


def test_deeply_nested_gamma_and_huge_integers_are_input_errors():
    deep = 0.0
    for _ in range(100_000):
        deep = [deep]
    with pytest.raises(InputError) as e:
        resolve({"gamma": deep})
    assert e.value.field.startswith("gamma") and len(str(e.value)) < 2000
    with pytest.raises(InputError) as e:
        resolve({"every": 10**5000})  # str() of this int is refused by Python
    assert e.value.field == "every" and "digits" in str(e.value)


def test_every_violated_limit_is_reported_in_one_message():
    with pytest.raises(InputError) as e:
        resolve({"dt": 0, "t_final": -1, "rtol": 1.0})
    fields = [x.field for x in e.value.errors]
    assert fields == ["dt", "t_final", "rtol"] and all(f in str(e.value) for f in fields)


def test_the_every_and_dt_hints_are_accepted():
    t_final, dt = 1000.0, 2e-5  # 50,000,000 steps: the most allowed
    with pytest.raises(InputError) as e:
        resolve({"dt": dt, "t_final": t_final, "every": 1})  # unset, every would be this hint, said
    hint = int(e.value.allowed.split("≥")[1].split()[0])
    assert hint == min_every(50_000_000, LIMITS["max_rows"])
    plan = resolve({"dt": dt, "t_final": t_final, "every": hint})  # the hint is accepted...
    assert output_rows(50_000_000, hint) <= LIMITS["max_rows"] < output_rows(50_000_000, hint - 1)  # ...and least
    assert plan.every == hint
    with pytest.raises(InputError) as e:
        resolve({"dt": 1e-6, "t_final": 3e5 / 7, "every": 10**6})
    dt_hint = float(e.value.allowed.split("dt ≥ ")[1].split()[0])
    resolve({"dt": dt_hint, "t_final": 3e5 / 7, "every": 10**6})


def test_an_overflowing_initial_state_is_refused_and_a_later_overflow_ends_diverged_and_finite():
    with pytest.raises(InputError) as e:
        simulate({"initial": {"u1": 1e154}, "t_final": 1}, progress=False)
    assert e.value.field == "initial" and "overflow" in str(e.value)
    run = simulate({"initial": {"u1": 1e152}, "t_final": 1}, progress=False)
    assert run.status == "diverged"
    for v in [run.t, run.energy, *run.state.values(), *run.violation.values()]:
        assert np.all(np.isfinite(v))
    s = run.summary
    assert math.isfinite(s["final_energy_drift"]) and math.isfinite(s["max_abs_energy_drift"])
    assert all(math.isfinite(v) for v in s["max_abs_violation"].values())


def test_prepare_loads_every_switch_target_before_the_clock_starts(monkeypatch):
    """On a first start a switch target's kernel and loop were compiled inside the timed loop
    (16–31 s against a 10 s limit): every kernel a run uses must be loaded before the clock
    starts, and nothing may be requested while it runs."""
    from nmkane_core.kernel.built import Built

    sim = sys.modules["nmkane_core.run.simulate"]
    phase = {"now": "setup"}
    requested: dict[str, set] = {"setup": set(), "timed": set()}
    kernel = Built.kernel

    here = threading.get_ident()  # this test's run: not a web app's warm-up thread left running

    def spy(self, variant=None):
        if threading.get_ident() == here:
            requested[phase["now"]].add(variant)
        return kernel(self, variant)

    def timed(fn):
        def run(*a, **k):
            phase["now"] = "timed"
            try:
                return fn(*a, **k)
            finally:
                phase["now"] = "setup"

        return run

    monkeypatch.setattr(Built, "kernel", spy)
    monkeypatch.setattr(sim, "integrate", timed(sim.integrate))
    for integrator in ("kutta-merson", "kutta-merson-adaptive"):
        for v in requested.values():
            v.clear()
        run = simulate(
            {
                "system": "appell-hamel",
                "model": "nonlinear",
                "initial": {"u2": 0},
                "t_final": 1,
                "integrator": integrator,
            },
            progress=False,
        )
        assert run.summary["switches"], "the run should switch models"
        assert {"nonlinear", "linear"} <= requested["setup"], requested  # seen in this thread
        assert not requested["timed"], requested  # every kernel was loaded before the clock started


def test_a_progress_bar_is_drawn_on_a_terminal_that_reports_no_size():
    """A fresh pseudo-terminal has 0 rows and 0 columns (``script``, container consoles):
    tqdm took that as −1 rows and drew nothing during long CLI runs."""
    code = (
        "from nmkane_core.run.simulate import simulate\n"
        "simulate({'dt': 0.0002, 'integrator': 'rk4', 't_final': 1000, 'every': 10**6})\n"
        "simulate({'dt': 0.01, 't_final': 1})\n"
    )
    master, slave = pty.openpty()  # size 0 × 0
    proc = subprocess.Popen(
        [sys.executable, "-c", code],
        stderr=slave,
        stdout=subprocess.DEVNULL,
        env={**os.environ, "PYTHONPATH": ROOT},
        cwd=ROOT,
    )
    os.close(slave)
    out = b""
    end = time.monotonic() + 300
    while time.monotonic() < end:
        ready, _, _ = select.select([master], [], [], 1.0)
        if ready:
            try:
                chunk = os.read(master, 65536)
            except OSError:
                break
            if not chunk:
                break
            out += chunk
        elif proc.poll() is not None:
            break
    proc.wait(60)
    os.close(master)
    assert proc.returncode == 0, out[-2000:]
    assert b"simulating:" in out and b"%|" in out and b"t = " in out, out[-2000:]


def test_bench_exits_0_when_a_target_is_missed_unless_strict(monkeypatch, capsys):
    import nmkane_core.bench.rows as bench

    rows = [
        {"workload": "fast", "wall_s": 0.1, "evals_per_s": None, "target": "≤ 1 s", "pass": True, "note": ""},
        {"workload": "slow", "wall_s": 9.0, "evals_per_s": None, "target": "≤ 1 s", "pass": False, "note": ""},
    ]
    monkeypatch.setattr(bench, "run_bench", lambda quick=False, log=print, long=False: rows)
    assert bench.main() == 0
    out = capsys.readouterr().out
    assert "PASS" in out and "FAIL" in out and "1 of 2 targets missed" in out
    assert bench.main(strict=True) == 1
    from nmkane_core.cli import main as cli_main

    assert cli_main(["bench"]) == 0 and cli_main(["bench", "--strict"]) == 1


def test_validate_settings_keeps_valid_settings():
    s = validate_settings({"system": "appell-hamel", "dt": 0.01, "t_final": 2, "every": 3, "gamma": -1})
    assert s.dt == 0.01 and s.every == 3 and s.gamma == -1
