"""The compiled loops' rank-robust constraint solve on closed-loop mechanisms: the IFToMM
N-four-bar (A02, N = 2) through its singular horizontal position, the over-constrained
parallelogram (all four closure equations declared), and the ``solve`` setting's errors; the
A02 runs' numbers do not depend on the CPU the kernels are compiled for.
The numpy reference's solve is tested in test_iftomm.py; these run ``simulate``."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from nmkane_core import register, simulate, unregister
from nmkane_core.declare.system import System
from nmkane_core.errors import InputError
from nmkane_core.schema import SOLVES
from nmkane_core.systems import iftomm_a02, iftomm_a04

PARALLELOGRAM = "test-redundant-parallelogram"


@pytest.fixture(scope="module")
def a02():
    return "iftomm-a02"  # built in: N = 2


@pytest.fixture(scope="module")
def parallelogram():
    system = System(
        name=PARALLELOGRAM,
        title="three-crank parallelogram, four closure equations",
        variants=lambda: iftomm_a04.parallelogram_model(redundant=True),
        parameters={k: v for k, v in iftomm_a04.PARAMETERS.items() if k in ("L", "m", "g")},
        default_initial=iftomm_a04.parallelogram_state(),
        default_dt=1e-3,
        default_t_final=1.0,
        default_integrator="kutta-merson",
        default_gamma1=-20.0,
        default_gamma2=-100.0,
        default_projection="yoon",
    )
    register(system)
    yield PARALLELOGRAM
    unregister(PARALLELOGRAM)


def _model_state(run, names):
    return np.column_stack([run.state[k] for k in names])


def _a02_acceptance(run):
    qn, un = iftomm_a02.names(2)
    x = _model_state(run, (*qn, *un))
    return x, iftomm_a02.acceptance(run.t, x, 2, energy=run.energy)


@pytest.mark.parametrize("solve", ["robust", "paper"])
def test_a02_kutta_merson_passes_the_singular_position_on_the_exact_motion(a02, solve):
    """Δt = 1e-3 past t = 3.32 s, where main's loops used to end ``diverged`` (energy 1e24 J):
    horizontal passages, B0 within 1e-6 of the exact parallelogram motion, |ΔE| ≤ 1e-6.  The
    default ``auto`` over the benchmark's 10 s: test_iftomm.py.  With fixed steps and the
    projection the paper's fixed partition passes too: no stage lands within 1e-10 of the
    singular position."""
    r = simulate({"system": a02, "dt": 1e-3, "t_final": 4.0, "solve": solve}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    x, acc = _a02_acceptance(r)
    assert np.count_nonzero(np.diff(np.sign(np.sin(x[:, 0]))) != 0) >= 2  # it did cross, more than once
    assert acc["B0_position"] < 1e-6 and acc["B0_velocity"] < 1e-6
    assert r.summary["max_abs_energy_drift"] < 1e-6
    robust = r.summary["robust_solve"]
    assert robust["evaluations"] > 0 if solve == "robust" else robust is None  # the paper's own path


def test_a02_adaptive_steps_without_projection_stop_at_the_bifurcation(a02):
    """What the catalogue's "what to try" says: adaptive steps without the projection close in
    on the singular position and cannot cross it — the paper's partition stops there (J2
    singular at 0.714 s), auto alternates between the partition and the robust solve as the steps
    shrink and ends at the same instant (the step size below its minimum) — with the cranks
    drifted apart by about 1e-7 rad and the energy nearly constant.  (With fused multiply-adds in
    the kernels, auto went on along the other branch until 1.78 s: which way a state off the
    branch goes at the crossing is decided by round-off.)  With only the steps near the singular
    position projected (``singular_projection``, on unless turned off) the run goes through."""
    base = {"system": a02, "integrator": "kutta-merson-adaptive", "projection": "none", "t_final": 1.5}
    near = simulate(base, progress=False)
    assert near.summary["status"] == "ok" and near.summary["robust_solve"]["near_singular_projections"] > 0
    base["singular_projection"] = False
    paper = simulate({**base, "solve": "paper"}, progress=False)
    assert paper.summary["status"] == "singular" and "J2" in paper.summary["message"]
    assert paper.t[-1] == pytest.approx(0.714, abs=2e-3)
    auto = simulate(base, progress=False)
    assert auto.summary["status"] == "failed" and "step size fell below its minimum" in auto.summary["message"]
    assert auto.t[-1] == pytest.approx(0.714, abs=2e-3)
    assert {round(s["t"], 3) for s in auto.summary["switches"]} == {0.714}
    asymmetry = np.abs(np.asarray(auto.state["th2"]) - auto.state["th0"]).max()
    assert 1e-8 < asymmetry < 1e-6 and auto.summary["max_abs_energy_drift"] < 1e-6


def test_a02_without_projection_at_small_steps_drifts_off_the_parallelogram(a02):
    """What to try, its last experiment: without the projection at Δt = 1e-4 the asymmetry grows at
    each passage — after 10 s B0 is millimetres off the exact motion and the energy has drifted by
    about 1e-2 J — where the default projection keeps both near 1e-11, and so does projecting only
    the steps near the singular position (projection none, singular_projection on)."""
    base = {"system": a02, "dt": 1e-4, "t_final": 10.0, "every": 10}
    off = {"projection": "none", "singular_projection": False}
    drift = _a02_acceptance(simulate({**base, **off}, progress=False))[1]
    kept = _a02_acceptance(simulate(base, progress=False))[1]
    near = _a02_acceptance(simulate({**base, "projection": "none"}, progress=False))[1]
    assert 1e-3 < drift["B0_position"] < 1e-2 and 3e-3 < drift["energy_drift"] < 3e-2, drift
    assert kept["B0_position"] < 1e-10 and kept["energy_drift"] < 1e-10, kept
    assert near["B0_position"] < 1e-9 and near["energy_drift"] < 1e-9, near


def test_a02_declares_the_mass_metric_projection_as_its_default(a02):
    r = simulate({"system": a02, "t_final": 0.01}, progress=False)
    assert r.settings["projection"] == "yoon"


def test_redundant_parallelogram_runs_ok_on_its_exact_motion(parallelogram):
    """All four closure equations (rank 3) declared: no square J2 exists, the robust solve runs
    it through the first horizontal passage (t ≈ 0.71 s) on the exact pendulum motion."""
    r = simulate({"system": parallelogram}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    x = _model_state(r, ("th0", "th1", "th2", "ph", "dth0"))
    th, w = iftomm_a02.exact_motion(r.t, 2, x[0, 0], x[0, 4])
    assert np.any(np.diff(np.sign(np.cos(x[:, 0]))) != 0)
    assert np.abs(np.cos(x[:, 0]) - np.cos(th)).max() < 1e-6 and np.abs(x[:, 4] - w).max() < 1e-6
    assert np.abs(x[:, 1] - x[:, 0]).max() < 1e-6 and np.abs(x[:, 3]).max() < 1e-6
    assert r.summary["max_abs_energy_drift"] < 1e-6
    assert r.summary["robust_solve"]["evaluations"] > 0


def test_the_paper_solve_is_refused_for_redundant_constraints(parallelogram):
    with pytest.raises(InputError, match="solve") as err:
        simulate({"system": parallelogram, "solve": "paper"}, progress=False)
    assert err.value.value == "paper" and "robust" in err.value.allowed


def test_a_bad_solve_value_names_the_field_the_value_and_the_choices():
    with pytest.raises(InputError) as err:
        simulate({"system": "iftomm-a01", "t_final": 1.0, "solve": "fast"}, progress=False)
    e = err.value
    assert e.field == "solve" and e.value == "fast"
    assert all(c in e.allowed for c in ("auto", "paper", "robust"))


def test_every_model_with_constraints_has_the_robust_solve_a_declared_partition_too():
    """A01 declares its partition (and defaults to the paper's solve): the rank-robust solve and
    auto are one option away, on the same motion (issue 42; before, solve="robust" was refused)."""
    runs = {s: simulate({"system": "iftomm-a01", "t_final": 1.0, "solve": s}, progress=False) for s in SOLVES}
    assert runs["paper"].settings["solve"] == "paper" and runs["paper"].summary["robust_solve"] is None
    assert runs["robust"].summary["robust_solve"]["evaluations"] > 0
    for s, r in runs.items():
        assert r.summary["status"] == "ok", (s, r.summary["message"])
        assert np.allclose(r.state["x"], runs["paper"].state["x"], atol=1e-8), s


@pytest.mark.parametrize(
    "step", [{"dt": 1e-3}, {"dt": 5e-4}, {"dt": 2e-4}, {"dt": 1e-4}, {"integrator": "kutta-merson-adaptive"}]
)
def test_a02_from_45_degrees_follows_the_exact_motion_for_10_s_at_every_step_size(a02, step):
    """The closed-loop issue's runs: A02 with N = 2 started at 45° with ẋ_B0 = 1 m/s (the
    catalogue's defaults otherwise: solve auto, Γ1 = −20, Γ2 = −100, the Yoon projection) over
    10 s — fourteen passages through the horizontal position — at Δt = 1e-3, 5e-4, 2e-4, 1e-4
    and with adaptive steps: ``ok``, B0 within 2e-7 of the exact motion (1e-6 asked), |ΔE| ≤ 1e-6.
    Measured: ≤ 2.1e-10 m and ≤ 2.3e-9 m/s at every step, the same bits on every CPU (the next
    test).  With fused multiply-adds in the kernels Δt = 2e-4 was 4.1e-7 m/s off on one x86-64
    machine and 1.2e-6 on another (a round-off asymmetry between the cranks, amplified at a
    passage: docs/closed-loops.md §7.4); without the Baumgarte terms' fade on the vanishing
    closure rows (symbolic.robust.BAUMGARTE_FADE) round-off asymmetries of 1e-16 to 1e-13 in the
    start gave up to 5.8e-7 (2.8e-8 with it)."""
    th0 = np.pi / 4
    initial = {"th0": th0, "dth0": -1.0 / np.sin(th0)}  # ẋ_B0 = −L sin θ0 · θ̇0 = 1 m/s
    r = simulate({"system": a02, "t_final": 10.0, "initial": initial, "every": 10, **step}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    x, acc = _a02_acceptance(r)
    assert x[0, 0] == pytest.approx(th0) and np.count_nonzero(np.diff(np.sign(np.sin(x[:, 0]))) != 0) >= 12
    assert acc["B0_position"] < 2e-7 and acc["B0_velocity"] < 2e-7, acc
    assert acc["energy_drift"] < 1e-6 and r.summary["max_abs_energy_drift"] < 1e-6


#: the step-size test's run at Δt = 2e-4, in a process whose compiled core is built for this
#: machine's CPU (FMA and vector instructions available): the state's rows, the acceptance numbers
_GENERIC_CPU_RUN = """
import json, sys
import numpy as np
from nmkane_core import simulate
from nmkane_core.systems import iftomm_a02
th0 = np.pi / 4
r = simulate({"system": "iftomm-a02", "t_final": 10.0, "dt": 2e-4, "every": 10,
              "initial": {"th0": th0, "dth0": -1.0 / np.sin(th0)}}, progress=False)
qn, un = iftomm_a02.names(2)
x = np.column_stack([r.state[k] for k in (*qn, *un)])
np.save(sys.argv[1], x)
print(json.dumps({"status": r.summary["status"], **iftomm_a02.acceptance(r.t, x, 2, energy=r.energy)}))
"""


def test_a02_core_compiled_for_this_cpu_gives_the_portable_builds_numbers(a02, tmp_path):
    """The step-size test's run at Δt = 2e-4 (the one a 2-core AMD EPYC machine failed, 1.2e-6 m/s
    off, while another machine passed) with the compiled core built for this machine's CPU
    (``-march=native``: its fused multiply-add instructions available), in a process of its own on
    an empty cache, agrees with this process's portable build to 1e-12 at every row, and both stay
    on the exact motion.  With contraction allowed (gcc's default) the two would differ by ~4e-7 m/s
    after the passage at t = 3.88 s on an FMA machine: this fails wherever the code rounds by the CPU."""
    th0 = np.pi / 4
    initial = {"th0": th0, "dth0": -1.0 / np.sin(th0)}
    host = simulate({"system": a02, "t_final": 10.0, "dt": 2e-4, "every": 10, "initial": initial}, progress=False)
    env = {
        **os.environ,
        "NMKANE_CORE_CFLAGS": "-march=native",
        "NMKANE_CACHE_DIR": str(tmp_path / "cache"),
    }
    rows = tmp_path / "generic.npy"
    out = subprocess.run(
        [sys.executable, "-c", _GENERIC_CPU_RUN, str(rows)], env=env, capture_output=True, text=True, timeout=600
    )
    assert out.returncode == 0, out.stderr[-3000:]
    generic = json.loads(out.stdout.strip().splitlines()[-1])
    qn, un = iftomm_a02.names(2)
    x = _model_state(host, (*qn, *un))
    assert generic["status"] == host.summary["status"] == "ok"
    assert np.abs(np.load(rows) - x).max() <= 1e-12
    assert generic["B0_velocity"] < 2e-7 and _a02_acceptance(host)[1]["B0_velocity"] < 2e-7
