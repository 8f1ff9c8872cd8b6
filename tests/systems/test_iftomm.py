"""The IFToMM multibody benchmarks A01–A05 against their acceptance conditions, and the
closed-loop cases of docs/closed-loops.md (the N-four-bar through its singular position,
redundant closure equations, a model without a partition).

Which path each test uses: the benchmarks' own cases run the compiled kernels through
``simulate`` with the catalogue's names (A02 and A04 on the compiled rank-robust solve; more
of A02 on the compiled path in test_closed_loops_compiled.py); the numpy reference's
rank-robust solve (``integrate_reference`` with ``solve="auto"`` and the mass-metric
projection) is tested here too — marked ``reference path`` — and is A04's oracle."""

import math

import numpy as np
import pytest

from nmkane_core import get_system, simulate
from nmkane_core.errors import SingularMatrix
from nmkane_core.integrate.methods import KUTTA_MERSON
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import default_state
from nmkane_core.symbolic.derivation import derive
from nmkane_core.symbolic.reference import (
    ConstraintsInconsistent,
    ReferenceKernel,
    integrate_reference,
    integrate_reference_adaptive,
)
from nmkane_core.systems import iftomm_a01, iftomm_a02, iftomm_a03, iftomm_a04, iftomm_a05


def _x0(md, state):
    return np.array([state[str(s)] for s in md.q + md.u], float)


def _reference_run(ref, x0, p, dt, T, m, **kw):
    ref.reset()
    G1, G2 = -20 * np.eye(m), -100 * np.eye(m)
    kw.setdefault("solve", "auto")
    kw.setdefault("project", True)
    t, xs = integrate_reference(ref, x0, p, dt, round(T / dt), KUTTA_MERSON, None, G1, G2, **kw)
    E = np.array([ref.energy(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
    return t, xs, E


# ---------------------------------------------------------------------------------- A01
def test_a01_declares_the_benchmarks_own_case():
    s = get_system("iftomm-a01")
    assert (s.default_t_final, s.default_dt, s.default_integrator) == (2000.0, 1e-3, "kutta-merson")
    assert s.default_initial == {"x": 1.0, "y": 0.0, "u1": 0.0, "u2": 0.0}  # horizontal, at rest, x = +1 m
    assert {p.name: p.default for p in s.parameters} == {"L": 1.0, "m": 1.0, "g": 9.81}


@pytest.mark.parametrize("model", ["cartesian", "cartesian-y"])
def test_a01_pendulum_follows_the_exact_motion(model):
    """Compiled path: P1 within 1e-9 m of the elliptic-function solution over 10 s (the
    benchmark asks 1e-3).  ``cartesian-y`` starts where its J2 = 2y is 0: the run switches to
    the equivalent partition and back (listed in the summary)."""
    r = simulate({"system": "iftomm-a01", "model": model, "t_final": 10.0}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    assert iftomm_a01.acceptance(r.t, r.state["x"], r.state["y"])["P1_position"] < 1e-9
    assert r.summary["max_abs_energy_drift"] < 1e-8
    assert (len(r.summary["switches"]) > 0) == (model == "cartesian-y")


# ---------------------------------------------------------------------------------- A02
@pytest.fixture(scope="module")
def a02():
    md = iftomm_a02.model(2)
    return md, ReferenceKernel(derive(md)), np.array([1.0, 1.0, 9.81])


def test_a02_rods_model_equals_kanes_method():
    import sympy as sp

    a, b = iftomm_a02.model(2), iftomm_a02.model(2, via="mechanics")
    assert sp.simplify(a.Q - b.Q) == sp.zeros(5, 5)
    assert sp.simplify(a.P - b.P) == sp.zeros(5, 1)
    assert sp.simplify(a.energy - b.energy) == 0
    assert all(sp.simplify(a.holonomic[k] - b.holonomic[k]) == 0 for k in a.holonomic)


def test_a02_without_partition_is_accepted_and_the_rank_drops_at_the_horizontal_position():
    md = iftomm_a02.model(2, partition=False)
    assert md.u_independent == () and md.m == 4
    ref = ReferenceKernel(derive(md))
    p = np.array([1.0, 1.0, 9.81])
    rep = ref.constraint_report(0.0, _x0(md, iftomm_a02.initial_state(2, theta0=0.7)), p)
    assert (rep["rank"], rep["independent_speeds"], rep["redundant"]) == (4, 1, [])
    assert len(rep["u_dependent"]) == 4 and len(rep["q_dependent"]) == 4
    flat = ref.constraint_report(0.0, _x0(md, {**iftomm_a02.initial_state(2), "th0": 0.0, "th1": 0.0, "th2": 0.0}), p)
    assert (flat["rank"], flat["independent_speeds"]) == (2, 3)  # 1 → N + 1 degrees of freedom
    assert sorted(flat["redundant"]) == ["close1_x", "close2_x"]


def test_a02_paper_solve_stops_at_the_horizontal_position_the_robust_one_goes_on(a02):
    md, ref, p = a02
    inertia, K = iftomm_a02.pendulum_constants(2)
    state = iftomm_a02.initial_state(2)
    for th in (1e-3, 1e-7):  # near it both solves give the exact θ̈ = −K/I cos θ
        x = _x0(md, {**state, "th0": th, "th1": th, "th2": th})
        for solve in ("paper", "robust"):
            assert ref.rhs(0.0, x, p, solve=solve)[5] == pytest.approx(-K / inertia * math.cos(th), rel=1e-12)
    x = _x0(md, {**state, "th0": 0.0, "th1": 0.0, "th2": 0.0})
    with pytest.raises(SingularMatrix):
        ref.rhs(0.0, x, p)
    xd = ref.rhs(0.0, x, p, solve="robust")  # exactly there: the vanishing rows dropped, a finite answer
    assert np.all(np.isfinite(xd)) and ref.last.rank == 2


@pytest.mark.parametrize("solve", ["robust", "auto"])
def test_a02_crosses_the_singular_position_on_the_exact_motion(a02, solve):
    """Reference path: the first horizontal passage (t ≈ 0.71 s) at Δt = 1e-3 with Kutta–Merson,
    Γ1 = −20, Γ2 = −100 and the projection: B0 within 1e-6 of the exact parallelogram motion,
    |ΔE| ≤ 1e-6 (scripts/closed_loops_validate.py runs the benchmark's 10 s).  ``auto`` keeps
    the paper's path wherever its J2 is well-conditioned — here everywhere but within 1e-10
    of the horizontal position, where the closure rows vanish (see test above)."""
    md, ref, p = a02
    t, xs, E = _reference_run(ref, _x0(md, iftomm_a02.initial_state(2)), p, 1e-3, 0.8, 4, solve=solve)
    assert np.any(np.diff(np.sign(np.sin(xs[:, 0]))) != 0)  # it did cross
    acc = iftomm_a02.acceptance(t, xs, 2, energy=E)
    assert acc["B0_position"] < 1e-6 and acc["B0_velocity"] < 1e-6 and acc["energy_drift"] < 1e-6


def test_a02_adaptive_step_passes_the_singular_position_with_the_tangent_error(a02):
    """Reference path: adaptive Kutta–Merson (the run defaults rtol 1e-10, atol 1e-12) through
    the first passage.  The compiled adaptive run stops ``singular`` at t = 0.714 s: its error
    estimate sees the amplified asymmetry and shrinks the step onto the singular point.  With
    the error estimate's components along the constraint normals removed (they are the
    projection's business) the step stays large and the motion exact."""
    md, ref, p = a02
    ref.reset()
    G1, G2 = -20 * np.eye(4), -100 * np.eye(4)
    t, xs, rejected = integrate_reference_adaptive(
        ref, _x0(md, iftomm_a02.initial_state(2)), p, 0.8, KUTTA_MERSON, None, G1, G2, solve="auto"
    )
    assert t[-1] == pytest.approx(0.8) and np.any(np.diff(np.sign(np.sin(xs[:, 0]))) != 0)
    E = np.array([ref.energy(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
    acc = iftomm_a02.acceptance(t, xs, 2, energy=E)
    assert acc["B0_position"] < 1e-6 and acc["B0_velocity"] < 1e-6 and acc["energy_drift"] < 1e-6
    assert len(t) < 400 and rejected < 10


def test_a02_catalogue_entry_declares_the_benchmark_with_N_as_constructor_argument():
    s = get_system("iftomm-a02")  # built in with N = 2, the case OpenSim 3.2 times
    assert s.name == "iftomm-a02" and s.default_t_final == 10.0 and s.default_dt == 1e-3
    assert (s.default_integrator, s.default_projection) == ("kutta-merson", "yoon")
    assert len(built(s).coordinates) == 5
    assert s.default_initial["dth0"] == -1.0 and s.default_initial["th1"] == math.pi / 2  # ẋ_B0 = 1 m/s
    assert iftomm_a02.iftomm_a02(40).name == "iftomm-a02-n40"
    assert len(iftomm_a02.names(40)[0]) == 81


def test_a02_benchmark_case_on_the_compiled_path_follows_the_exact_motion():
    """Compiled path, ``nmkane run iftomm-a02`` with no options: N = 2, 10 s at Δt = 1e-3,
    Kutta–Merson, solve auto, the Yoon projection — ten horizontal passages, B0 within 1e-8 m
    and 1e-8 m/s of the exact parallelogram motion (measured 1.6e-10, 1.1e-9; the benchmark
    asks 1e-3), |ΔE| ≤ 1e-9 J (3.4e-11)."""
    r = simulate({"system": "iftomm-a02"}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    assert r.t[-1] == pytest.approx(10.0) and r.settings["solve"] == "auto"
    qn, un = iftomm_a02.names(2)
    x = np.column_stack([r.state[k] for k in (*qn, *un)])
    assert np.count_nonzero(np.diff(np.sign(np.sin(x[:, 0]))) != 0) >= 9  # the passages
    acc = iftomm_a02.acceptance(r.t, x, 2, energy=r.energy)
    assert acc["B0_position"] < 1e-8 and acc["B0_velocity"] < 1e-8, acc
    assert acc["energy_drift"] < 1e-9 and r.summary["max_abs_energy_drift"] < 1e-9


# -------------------------------------------------------------------- the redundant parallelogram
@pytest.fixture(scope="module")
def parallelogram():
    md = iftomm_a04.parallelogram_model(redundant=True)
    return md, ReferenceKernel(derive(md)), np.array([1.0, 1.0, 9.81])


def test_redundant_parallelogram_is_declared_with_all_four_closure_equations(parallelogram):
    md, ref, p = parallelogram
    assert md.m == 4 and len(md.u_independent) == 1  # 4 + 1 > 4 speeds: redundant, accepted
    rep = ref.constraint_report(0.0, _x0(md, iftomm_a04.parallelogram_state(theta0=1.0)), p)
    assert (rep["rank"], rep["independent_speeds"], len(rep["redundant"])) == (3, 1, 1)


def test_redundant_parallelogram_runs_on_its_exact_motion(parallelogram):
    """Reference path: over the first horizontal passage, all four closure equations declared."""
    md, ref, p = parallelogram
    t, xs, E = _reference_run(ref, _x0(md, iftomm_a04.parallelogram_state()), p, 1e-3, 0.8, 4)
    # the same pendulum as the N-four-bar with N = 2: I = 3 m L², K = 3.5 m g L
    assert iftomm_a04.parallelogram_constants() == pytest.approx(iftomm_a02.pendulum_constants(2))
    th, w = iftomm_a02.exact_motion(t, 2, xs[0, 0], xs[0, 4])
    assert np.abs(np.cos(xs[:, 0]) - np.cos(th)).max() < 1e-6 and np.abs(xs[:, 4] - w).max() < 1e-6
    assert np.abs(E - E[0]).max() < 1e-6


def test_a_state_the_redundant_closures_cannot_come_from_ends_with_the_reason(parallelogram):
    md, ref, p = parallelogram
    x = _x0(md, iftomm_a04.parallelogram_state(theta0=1.0))
    x[2] += 1e-3  # crank 2 off by 1 mrad: the four closures disagree
    ref.reset()
    with pytest.raises(ConstraintsInconsistent, match="inconsistent"):
        ref.rhs(0.0, x, p, None, -20 * np.eye(4), -100 * np.eye(4), solve="robust")


# ---------------------------------------------------------------------------------- A03
def test_a03_energy_balance_and_the_test_set_reference_solution():
    """Compiled path, the benchmark's own case: ΔU = T + V − E0 − τ(β − β0) stays at zero and the
    seven angles at t = 0.03 s match the CWI/Bari test set's reference solution."""
    r = simulate({"system": "iftomm-a03"}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    assert r.t[-1] == pytest.approx(0.03)
    assert r.summary["max_abs_energy_drift"] < 1e-8  # ΔU, J (E0 ≈ 1.44 J)
    got = np.array([r.state[n][-1] for n in iftomm_a03.NAMES])
    np.testing.assert_allclose(got, iftomm_a03.REFERENCE_003, rtol=1e-7, atol=1e-8)


# ---------------------------------------------------------------------------------- A04
@pytest.fixture(scope="module")
def bricard():
    red = iftomm_a04.bricard_model()
    classic = iftomm_a04.bricard_model(redundant=False)
    return red, ReferenceKernel(derive(red)), ReferenceKernel(derive(classic)), np.array([1.0, 1.0, 0.1, 9.81])


def test_a04_bricard_has_five_closure_equations_of_rank_four(bricard):
    _, ref, _, p = bricard
    rep = ref.constraint_report(0.0, np.zeros(10), p)
    assert (rep["m"], rep["rank"], rep["independent_speeds"]) == (5, 4, 1)
    assert rep["redundant"] == ["J6_axis_y"]


def test_a04_bricard_conserves_energy_and_moves_p3_as_the_non_redundant_declaration(bricard):
    """Reference path: released from rest (OpenSim's start), 1 s at Δt = 1e-3: |ΔE| ≤ 1e-6 and
    P3 as with the redundant equation left out (the paper's path with 4 equations).  Compiled
    path, ``nmkane run iftomm-a04`` with no options (the benchmark's 10 s at Δt = 1e-3, all five
    equations, the compiled rank-robust solve): |ΔE| ≤ 1e-10 J (measured 7.5e-13), P3 over the
    first second on both reference runs within 1e-8 m, and the swing of its period (q1 from 0 to
    π and back, twice in 10 s)."""
    _, ref, classic, p = bricard
    t, xs, E = _reference_run(ref, np.zeros(10), p, 1e-3, 1.0, 5)
    _, xc, _ = _reference_run(classic, np.zeros(10), p, 1e-3, 1.0, 4, solve="paper")
    assert np.abs(E - E[0]).max() < 1e-6
    P3 = np.array([ref.outputs(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
    P3c = np.array([classic.outputs(ti, xi, p) for ti, xi in zip(t, xc, strict=True)])
    assert np.abs(P3 - P3c).max() < 1e-8
    assert np.ptp(P3[:, 1]) > 0.1  # it does move

    r = simulate({"system": "iftomm-a04"}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    assert r.t[-1] == pytest.approx(10.0) and r.summary["robust_solve"]["min_rank"] == 4
    assert r.summary["max_abs_energy_drift"] < 1e-10
    x = np.column_stack([r.state[f"{c}{k}"] for c in "qu" for k in range(1, 6)])
    first = slice(0, len(t))
    np.testing.assert_allclose(r.t[first], t, atol=1e-12)
    P3r = np.array([ref.outputs(ti, xi, p) for ti, xi in zip(r.t[first], x[first], strict=True)])
    assert np.abs(P3r - P3).max() < 1e-8 and np.abs(P3r - P3c).max() < 1e-8
    assert np.ptp(r.state["q1"]) == pytest.approx(math.pi, abs=1e-6)
    assert np.count_nonzero(np.diff(np.sign(r.state["u1"])) != 0) >= 3  # back, forth, back


def test_a04_a_hard_push_at_the_default_step_runs_on_the_motion_of_a_fine_step():
    """What the catalogue's "what to try" says: at u1 = 5 rad/s the later Runge–Kutta stages of a
    1e-3 step are off the constraints by the step's truncation error, where the redundant
    equation misses by more than CONSISTENCY_TOL; consistency is judged at the accepted states
    (each step's first stage), so the run goes on, on the motion a ten times finer step gives.
    (Before, the first step ended the run as inconsistent.)"""
    base = {"system": "iftomm-a04", "initial": {"u1": 5.0}, "t_final": 0.5}
    hard = simulate(base, progress=False)
    assert hard.summary["status"] == "ok", hard.summary["message"]
    assert hard.summary["max_abs_energy_drift"] < 1e-8
    fine = simulate({**base, "dt": 1e-4}, progress=False)
    assert fine.summary["status"] == "ok", fine.summary["message"]
    for q in ("q1", "q2", "q3"):
        assert abs(hard.state[q][-1] - fine.state[q][-1]) < 1e-8


def test_inconsistent_constraints_end_a_run_at_an_accepted_state_not_at_a_trial_stage():
    """The rule of the compiled loops (kernel/csrc/loops.c ``robust_outcome``): the robust
    solve's "J u̇ = c inconsistent" ends the run at a step's first stage (an accepted state), and
    is ignored at a later stage (a trial state off the constraints by the truncation error)."""
    from nmkane_core.kernel.built import built
    from nmkane_core.kernel.constants import STATUS_INCONSISTENT, STATUS_OK

    mod, _ = built(get_system("iftomm-a04")).kernel()
    outcome = mod._robust_outcome
    for start, want in ((True, STATUS_INCONSISTENT), (False, STATUS_OK)):
        w = np.zeros(mod.OSV + 64)
        w[mod.OSV + mod.SV_STATUS] = 2.0  # the robust solve's verdict: inconsistent
        w[mod.OSV + mod.SV_USED] = 1.0
        w[mod.OSV + mod.SV_RANK] = 4.0
        stats = np.full(64, np.inf)
        stats[mod.STATS_SOLVE_LOG] = 0.0
        stats[mod.STATS_MAX_STAB] = 0.0
        stats[mod.STATS_ROBUST_EVALS] = 0.0
        order, log = np.zeros(mod.N + 1, np.int64), np.zeros((4, 16))
        assert outcome(0.1, 1e-3, w, stats, order, log, start) == want
        assert (stats[mod.STATS_SOLVE_LOG] == 1.0) == start  # logged only where it ends the run


# ---------------------------------------------------------------------------------- A05
def test_a05_flyball_governor_conserves_axial_momentum_and_only_dissipates():
    """Compiled path, the benchmark's 10 s at Δt = 1e-4 (the damped spring modes decay at
    8.1e3 s⁻¹: Kutta–Merson needs Δt < 4.4e-4): the angular momentum about the shaft is
    conserved, the energy never grows, the stiff springs stay within 1 mm of their length."""
    r = simulate({"system": "iftomm-a05"}, progress=False)
    assert r.summary["status"] == "ok", r.summary["message"]
    system = get_system("iftomm-a05")
    md = built(system).model()
    ref = ReferenceKernel(built(system).derivation())
    p = np.array([system.parameter(str(s)).default for s in md.params])
    x = np.column_stack([r.state[str(s)] for s in md.q + md.u])
    out = np.array([ref.outputs(0.0, xi, p) for xi in x[::50]])  # Hz, stretch1, stretch2
    assert np.abs(out[:, 0] - out[0, 0]).max() < 1e-9 * abs(out[0, 0])
    assert np.all(np.diff(r.energy) <= 1e-9 * abs(r.energy[0]))
    assert np.abs(out[:, 1:]).max() < 1e-3
    assert r.state["s"].min() > 0.0 and r.state["s"].max() < 1.0  # the slider stays on the shaft


def test_a05_step_above_the_stability_limit_is_not_ok():
    r = simulate({"system": "iftomm-a05", "dt": 5e-4, "t_final": 1.0}, progress=False)
    assert r.summary["status"] != "ok"


def test_iftomm_declarations_carry_their_published_parameters():
    assert iftomm_a05.PARAMETERS["k"].default == 8e5 and iftomm_a05.PARAMETERS["c"].default == 4e4
    assert iftomm_a03.VALUES["c0"][0] == 4530.0 and iftomm_a03.VALUES["mom"][0] == 0.033
    assert iftomm_a04.PARAMETERS["a"].default == 0.1
    assert (iftomm_a02.OPENSIM_CPU_S, iftomm_a03.OPENSIM_CPU_S, iftomm_a04.OPENSIM_CPU_S) == (0.455, 0.384, 0.258)


# ------------------------------------------------------------------------------- the scenes
CATALOGUE = ["iftomm-a01", "iftomm-a02", "iftomm-a03", "iftomm-a04", "iftomm-a05"]


def test_the_catalogue_holds_the_five_benchmarks():
    from nmkane_core.systems import BUILTIN

    assert [n for n in BUILTIN if n.startswith("iftomm-")] == CATALOGUE


@pytest.mark.parametrize("name", CATALOGUE)
def test_catalogue_benchmarks_have_scenes_that_compile(name):
    from nmkane_core.kernel.visuals import compile_visuals

    system = get_system(name)
    assert system.what_to_try and system.title.startswith("IFToMM")
    cv = compile_visuals(system)
    x = default_state(system)
    params = {p.name: p.default for p in system.parameters}
    poses = cv.poses({k: np.array([v]) for k, v in x.items()}, params)
    assert poses and all(np.all(np.isfinite(v)) for v in poses)
    assert np.all(np.isfinite(cv.sizes(params)))


@pytest.mark.parametrize("name", CATALOGUE)
def test_benchmark_scenes_name_only_state_values_and_parameters(name):
    system = get_system(name)
    md = built(system).model()
    vis = system.visuals()
    names = {str(s).removesuffix("(t)") for s in (*md.q, *md.u, *md.params)}
    for shape in vis.shapes:
        for f in (*shape.PARAM_FIELDS, *shape.STATE_FIELDS):
            for e in np.ravel(np.array(getattr(shape, f), dtype=object)):
                assert {str(s) for s in getattr(e, "free_symbols", set())} <= names, (shape, f)


def test_a04s_matrices_say_what_is_not_defined_instead_of_a_traceback(capsys, monkeypatch):
    """Redundant constraints have no square J2: A = −J2⁻¹J1 and T are not defined. The
    derivation says so (NotDefined); `nmkane matrices` prints what is defined and says why the
    rest is not, or refuses an explicit --matrix T on one line (before: sympy's "The system is
    inconsistent." as a traceback, and no matrices panel in the web page)."""
    from nmkane_core.cli import main
    from nmkane_core.errors import NotDefined
    from nmkane_core.kernel.built import built
    from nmkane_core.symbolic import shorten

    # the entries printed as derived: what is checked is what is said, not how short the entries
    # get (the command spends its whole 8 s simplifying budget on A04's, twice: 16 s of the test)
    budget = shorten.Budget
    monkeypatch.setattr(shorten, "Budget", lambda: budget(total_s=0.0))
    d = built(get_system("iftomm-a04")).derivation()
    assert d.matrix("J2").shape == (5, 4) and d.matrix("Q").shape == (5, 5)
    with pytest.raises(NotDefined, match="J2 is 5 × 4"):
        d.matrix("T")
    wide = ["--width", "100000"]  # each matrix as one block (narrower: entry by entry)
    assert main(["matrices", "iftomm-a04", "--matrix", "J2", *wide]) == 0
    assert main(["matrices", "iftomm-a04", *wide]) == 0
    out = capsys.readouterr().out
    assert out.count("J2 =") == 2 and "A1: not defined. A = −J2⁻¹J1" in out and "T =" not in out
    assert main(["matrices", "iftomm-a04", "--matrix", "T"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not defined for this model" in err[0]
