"""Singular configurations of the nonlinear Appell–Hamel model (φ̇ = 0), equivalent-model
switching, the spurious branch of (57), projection of inconsistent initial states."""

import subprocess
import sys

import numpy as np
import pytest

from nmkane_core import InputError
from nmkane_core.errors import InconsistentStateError
from nmkane_core.run.plan import resolve
from nmkane_core.run.simulate import simulate

KEYS = ("theta", "phi", "x", "y", "z", "u1", "u2", "u3", "u4", "u5")


def _final(run):
    return np.array([run.state[k][-1] for k in KEYS])


def test_start_with_wheel_not_rolling_switches_and_agrees_with_linear_model():
    s = {"system": "appell-hamel", "initial": {"u2": 0.0}, "dt": 0.005, "t_final": 10}
    nl = simulate({**s, "model": "nonlinear"})
    lin = simulate({**s, "model": "linear"})
    assert nl.status == "ok", nl.summary["message"]
    sw = nl.summary["switches"]
    assert sw[0]["t"] == 0.0 and sw[0]["from"] == "nonlinear" and sw[0]["to"] == "linear"
    assert sw[-1]["to"] == "nonlinear"  # back on the selected model once φ̇ has grown
    np.testing.assert_allclose(_final(nl), _final(lin), rtol=1e-9, atol=1e-9)
    # constraint values reported are those of the selected (nonlinear) model
    assert set(nl.violation) == {"rolling_speed", "no_side_slip", "thread"}
    assert nl.summary["max_abs_violation"]["rolling_speed"] < 1e-8


def test_without_switching_the_singular_start_stops_with_status_singular():
    run = simulate({"system": "appell-hamel", "initial": {"u2": 0.0}, "switching": False})
    assert run.status == "singular" and "φ̇ = 0" in run.summary["message"]
    assert len(run.t) == 1 and np.all(np.isfinite(run.state["u2"]))


@pytest.mark.parametrize("u2", [-2.0, -0.4])
def test_wheel_reversal_stays_on_the_physical_branch_and_agrees_with_linear_model(u2):
    s = {"system": "appell-hamel", "initial": {"u2": u2, "u1": 0.3}, "params": {"g": 1.0}, "dt": 0.01, "t_final": 15}
    nl = simulate({**s, "model": "nonlinear"})
    lin = simulate({**s, "model": "linear"})
    assert nl.status == "ok"
    assert nl.state["u2"][0] < 0 < nl.state["u2"][-1]  # φ̇ changed sign
    assert any(sw["to"] == "linear" for sw in nl.summary["switches"])
    np.testing.assert_allclose(_final(nl), _final(lin), rtol=1e-8, atol=1e-8)
    # physical branch: v_o = +aφ̇(cos θ, sin θ) (rolling (51)–(52)), not the spurious −aφ̇
    th, u1, u2_, u3 = (nl.state[k] for k in ("theta", "u1", "u2", "u3"))
    vox = u3 + 5.0 * u1 * np.sin(th)
    np.testing.assert_allclose(vox, u2_ * np.cos(th), atol=1e-7)


def test_switching_keeps_accuracy_near_the_singularity():
    """Slow reversal (g = 0.2): the switched nonlinear run is closer to a fine reference than
    the unswitched one, which loses accuracy as J2's row shrinks with φ̇."""
    s = {"system": "appell-hamel", "params": {"g": 0.2}, "initial": {"u2": -0.3, "u1": 0.2}, "t_final": 20}
    ref = simulate({**s, "model": "linear", "dt": 0.0005, "every": 40000})
    err = {}
    for switching in (True, False):
        r = simulate({**s, "model": "nonlinear", "dt": 0.05, "switching": switching, "every": 400})
        err[switching] = np.abs(_final(r) - _final(ref)).max()
    assert err[True] < err[False]


def test_adaptive_integrator_switches_too():
    run = simulate(
        {
            "system": "appell-hamel",
            "initial": {"u2": 0.0},
            "integrator": "kutta-merson-adaptive",
            "t_final": 5,
            "rtol": 1e-9,
            "atol": 1e-9,
        }
    )
    assert run.status == "ok" and run.summary["switches"][0]["to"] == "linear"


def test_full_state_on_the_spurious_branch_is_refused_with_a_message_that_says_so():
    spurious = dict(theta=0, phi=0, x=0, y=0, z=30, u1=1, u2=1, u3=-1, u4=5, u5=-0.5)
    with pytest.raises(InconsistentStateError) as e:
        resolve({"system": "appell-hamel", "model": "nonlinear", "initial": spurious})
    assert "spurious branch" in str(e.value)


def test_inconsistent_initial_state_is_projected_when_asked_and_the_correction_reported():
    bad = dict(theta=0.2, phi=0, x=0, y=0, z=30.3, u1=1, u2=1, u3=1.2, u4=5, u5=-0.5)
    with pytest.raises(InconsistentStateError) as e:
        resolve({"system": "appell-hamel", "initial": bad})
    assert "residuals" in str(e.value)
    run = simulate({"system": "appell-hamel", "initial": bad, "project_initial": True, "t_final": 1})
    assert run.status == "ok"
    corr = run.summary["initial_correction"]
    assert corr and abs(corr["z"]) > 0.1 and any("projected" in w for w in run.summary["warnings"])
    assert max(run.summary["max_abs_violation"].values()) < 1e-8


@pytest.mark.parametrize("gains", [{"gamma": 2.0}, {"gamma": [[-1.0, 0.0], [0.0, 0.5]]}])
def test_gains_with_nonnegative_eigenvalues_are_accepted_but_flagged(gains):
    run = simulate({"system": "appell-hamel", "t_final": 1, **gains})
    assert run.status in ("ok", "diverged")
    assert any("not stable" in w for w in run.summary["warnings"])


def test_stable_gains_are_not_flagged():
    run = simulate({"system": "sliding-particle", "gamma1": -20, "gamma2": -100, "t_final": 1})
    assert run.summary["warnings"] == []


def test_rcond_switch_is_validated():
    with pytest.raises(InputError) as e:
        resolve({"system": "appell-hamel", "rcond_switch": 2.0})
    assert e.value.field == "rcond_switch"


@pytest.mark.parametrize("integrator", ["kutta-merson", "kutta-merson-adaptive"])
def test_singular_start_with_no_cure_stops_as_singular_and_does_not_loop(integrator):
    """φ̇0 = 0 and the linear model not better than rcond_switch there (its T estimate is
    0.32 < 0.4): no switch is possible, so the run must stop as ``singular`` at once.  It
    used to retry the same step forever (found by the library fuzz test), ignoring even
    ``time_limit`` — hence a child process with a timeout: a regression fails, not hangs."""
    code = (
        "from nmkane_core.run.simulate import simulate\n"
        "r = simulate({'system': 'appell-hamel', 'initial': {'u2': 0.0}, 'rcond_switch': 0.4, "
        f"'integrator': '{integrator}'}}, progress=False, time_limit=5.0)\n"
        "print(r.status, len(r.t), r.summary['switches'], r.summary['message'])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    status, rows, rest = out.stdout.split(" ", 2)
    assert status == "singular" and rows == "1" and rest.startswith("[]") and "φ̇ = 0" in rest, out.stdout


def test_an_adaptive_run_stopped_before_its_first_step_keeps_one_row(monkeypatch):
    """A call that ends before its first row adds an empty chunk; the last row kept is the one
    before it, not whatever the empty chunk's buffer held (A02 started on its singular position
    returned t = [0, 0] in about half of the lesson's runs: the buffer is np.empty)."""
    from nmkane_core.integrate import calls

    made = calls.Rows.__init__

    def stale(self, *a, **k):  # buffers that hold an old time, as reused memory may
        made(self, *a, **k)
        self.t.fill(-1.0)

    monkeypatch.setattr(calls.Rows, "__init__", stale)
    s = {"system": "appell-hamel", "model": "nonlinear", "initial": {"u2": 0.0}, "switching": False}
    run = simulate({**s, "integrator": "kutta-merson-adaptive", "t_final": 1.0}, progress=False)
    assert run.status == "singular" and run.summary["steps"] == 0
    assert list(run.t) == [0.0]
