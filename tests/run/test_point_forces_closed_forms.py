"""Constraint forces against independent answers: closed forms of classic problems, Newton's
law where the coordinates make a force non-contributing, and the two Appell–Hamel models
against each other (the same motion: the same forces).  Relative errors ≤ 1e-8."""

import math

import numpy as np
import pytest

from nmkane_core import Parameter, System, accelerations, register, simulate
from nmkane_core.run.plan import resolve

PENDULUM = "test-cartesian-pendulum"
TH0 = 1.2  # rad from the downward vertical


def _pendulum():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    m, g, L = sp.symbols("m g L", positive=True)
    return MechanicalModel(
        name="cartesian",
        q=(x, y),
        u=(u1, u2),
        params=(m, g, L),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, -m * g]),
        holonomic={"rod": x**2 + y**2 - L**2},
        u_independent=(u1,),
        q_dependent=(y,),
        energy=m / 2 * (u1**2 + u2**2) + m * g * y,
    )


def _pendulum_forces():
    """The rod's pull on the bob: ψ̇ = 2(x ẋ + y ẏ), so R = λ ∂ψ̇/∂v = 2λ (x, y); its
    component toward the pivot is the tension."""
    import sympy as sp

    from nmkane_core.declare.forces import Forces, PointForce, constraint_force
    from nmkane_core.symbolic.model import plain_symbols

    x, y = plain_symbols("x y")
    r = sp.sqrt(x**2 + y**2)
    (R,) = constraint_force({"rod": (-2 * (x**2 + y**2) / r,)}, components=1)  # 2λ(x, y) · (−x, −y)/r
    return Forces(
        forces=(
            PointForce("rod", at=(x, y, 0), components=(R,), frame=sp.Matrix([-x / r, -y / r, 0]), labels=("tension",)),
        )
    )


@pytest.fixture(scope="module")
def pendulum():
    from nmkane_core.run.registry import unregister

    system = System(
        name=PENDULUM,
        variants=_pendulum,
        parameters={
            "m": Parameter(2.0, 0.0, 1e3, "kg"),
            "g": Parameter(9.81, 0.0, 1e3, "m/s²"),
            "L": Parameter(1.5, 0.0, 1e3, "m"),
        },
        default_initial={"x": 1.5 * math.sin(TH0), "y": -1.5 * math.cos(TH0), "u1": 0.0},
        forces=_pendulum_forces,
    )
    register(system)
    yield system
    unregister(PENDULUM)


def _rel(got, want):
    got, want = np.asarray(got, float), np.asarray(want, float)
    return float(np.max(np.abs(got - want)) / np.max(np.abs(want)))


def test_cartesian_pendulum_rod_tension_is_m_v2_over_L_plus_m_g_cos_theta(pendulum):
    run = simulate({"system": PENDULUM, "dt": 0.001, "t_final": 5.0, "gamma1": -20.0, "gamma2": -100.0, "every": 10})
    assert run.status == "ok"
    m, g = 2.0, 9.81
    x, y, u1, u2 = (run.state[k] for k in ("x", "y", "u1", "u2"))
    r = np.hypot(x, y)
    tension = m * (u1**2 + u2**2) / r + m * g * (-y / r)  # cos θ = −y/L
    assert _rel(run.point_forces["rod.tension"], tension) < 1e-8
    # energy conservation gives the tension from the angle alone: m g (3 cos θ − 2 cos θ0)
    assert _rel(run.point_forces["rod.tension"], m * g * (3 * (-y / r) - 2 * math.cos(TH0))) < 1e-8
    # the multiplier and the generalized force: F_c = Jᵀλ with J = 2 (x, y)
    lam = run.multipliers["rod"]
    assert _rel(run.constraint_forces["u1"], 2 * lam * x) < 1e-12
    assert _rel(run.constraint_forces["u2"], 2 * lam * y) < 1e-12
    assert run.summary["max_abs_point_force"]["rod"] == pytest.approx(np.max(tension), rel=1e-8)


def test_knife_edge_on_its_circle_feels_m_v_omega_sideways_and_no_torque():
    m, v, w = 1.7, 1.3, 0.6
    run = simulate(
        {"system": "knife-edge", "params": {"m": m}, "initial": {"u1": v, "u3": w}, "t_final": 10.0, "dt": 0.01}
    )
    assert _rel(run.point_forces["blade.lateral"], np.full(run.t.size, m * v * w)) < 1e-12
    assert np.max(np.abs(run.constraint_forces["u3"])) < 1e-12  # no torque about the vertical
    assert np.max(np.abs(run.constraint_forces["u1"])) < 1e-12  # nor along the blade
    # the force points to the centre of the circle: from the blade towards (x, y) + (v/ω) B.y
    th = run.state["theta"]
    np.testing.assert_allclose(run.point_forces["blade.lateral"] * -np.sin(th), m * v * w * -np.sin(th), atol=1e-12)


def test_chaplygin_sleigh_blade_force_is_m_v_omega_I_over_J():
    m, inertia, a = 1.0, 0.1, 0.5
    run = simulate({"system": "chaplygin-sleigh", "t_final": 10.0, "dt": 0.001, "every": 10})
    v, w = run.state["u1"], run.state["u3"]
    J = inertia + m * a**2
    assert _rel(run.point_forces["blade.lateral"], m * v * w * inertia / J) < 1e-8
    # and against the closed-form motion of time (module docstring of chaplygin_sleigh)
    v0, w0 = 0.1, 2.0
    V = math.sqrt((m * v0**2 + J * w0**2) / m)
    s = m * a * V / J * run.t + math.atanh(v0 / V)
    closed = m * (V * np.tanh(s)) * (math.sqrt(m / J) * V / np.cosh(s)) * inertia / J
    assert _rel(run.point_forces["blade.lateral"], closed) < 1e-8


def test_coin_rolling_upright_and_straight_feels_m_g_and_no_friction():
    m, g = 1.4, 9.81
    run = simulate(
        {
            "system": "rolling-disk",
            "params": {"m": m},
            "initial": {"theta": 0.0, "u3": 0.0, "u4": 0.0, "u5": 6.0},
            "t_final": 3.0,
        }
    )
    assert _rel(run.point_forces["contact.normal"], np.full(run.t.size, m * g)) < 1e-12
    for k in ("contact.longitudinal", "contact.lateral"):
        assert np.max(np.abs(run.point_forces[k])) < 1e-10 * m * g


def _disk_newton():
    """m a_C + m g ẑ of the coin from its kinematics (sympy, independently of the system's
    declaration): the total contact force, N components, as a function of (x, u̇)."""
    import sympy as sp

    x, y, psi, th, ph = sp.symbols("x y psi theta phi")
    q = (x, y, psi, th, ph)
    u = sp.symbols("u1:6")
    ud = sp.symbols("ud1:6")
    m, r, g = 1.0, 0.3, 9.81
    Rz = sp.Matrix([[sp.cos(psi), -sp.sin(psi), 0], [sp.sin(psi), sp.cos(psi), 0], [0, 0, 1]])
    Rx = sp.Matrix([[1, 0, 0], [0, sp.cos(th), -sp.sin(th)], [0, sp.sin(th), sp.cos(th)]])
    C = sp.Matrix([x, y, 0]) + Rz * Rx * sp.Matrix([0, 0, r])
    v = C.jacobian(q) * sp.Matrix(u)  # q̇ = u
    a = v.jacobian(q) * sp.Matrix(u) + v.jacobian(u) * sp.Matrix(ud)
    return sp.lambdify([q + u, ud], m * a + sp.Matrix([0, 0, m * g]), "numpy")


def test_coin_contact_force_is_newtons_m_a_plus_m_g_at_random_states():
    """Friction from λ (the multiplier route) and the normal force from the declared Newton
    route, both against m a_C + m g ẑ computed here from the coin's kinematics."""
    newton = _disk_newton()
    rng = np.random.default_rng(7)
    for _ in range(6):
        init = {
            "theta": rng.uniform(-0.6, 0.6),
            "psi": rng.uniform(-3, 3),
            "u3": rng.uniform(-2, 2),
            "u4": rng.uniform(-1, 1),
            "u5": rng.uniform(-8, 8),
        }
        plan = resolve({"system": "rolling-disk", "initial": init})
        state = dict(zip(plan.info.state_names, plan.x0, strict=True))
        acc = accelerations("rolling-disk", state)
        total = np.asarray(newton(plan.x0, [acc[f"u{i}"] for i in range(1, 6)]), float).ravel()
        psi = state["psi"]
        heading = np.array(
            [
                total[0] * math.cos(psi) + total[1] * math.sin(psi),
                -total[0] * math.sin(psi) + total[1] * math.cos(psi),
                total[2],
            ]
        )
        got = [acc.point_forces[f"contact.{k}"] for k in ("longitudinal", "lateral", "normal")]
        assert _rel(got, heading) < 1e-10


def test_sliding_particle_normal_force_from_the_curvature_in_both_formulations():
    """N = m g cos α + m v² κ on y = l0 − x²/l0 (tan α = 2x/l0, κ = (2/l0)/(1 + tan²α)^{3/2}),
    no tangential force; the nonminimal run by its multiplier, the minimal one by Newton."""
    for formulation in ("nonminimal", "minimal"):
        run = simulate(
            {
                "system": "sliding-particle",
                "formulation": formulation,
                "gamma1": -20.0,
                "gamma2": -100.0,
                "dt": 0.001,
                "t_final": 3.0,
            }
        )
        x, u1, u2 = (run.state[k] for k in ("x", "u1", "u2"))
        s = np.sqrt(1 + 4 * x**2)
        normal = 9.81 / s + (u1**2 + u2**2) * 2 / s**3
        assert _rel(run.point_forces["normal.normal"], normal) < 1e-8, formulation
        assert np.max(np.abs(run.point_forces["normal.tangential"])) < 1e-12 * np.max(normal), formulation
    at_rest = accelerations("sliding-particle", {"x": 1.0, "y": 0.0, "u1": 0.0, "u2": 0.0})
    assert at_rest.point_forces["normal.normal"] == pytest.approx(9.81 / math.sqrt(5), rel=1e-14)
    assert at_rest.multipliers["surface"] == pytest.approx(-9.81 / 5, rel=1e-14)
    assert at_rest.constraint_forces == pytest.approx({"u1": -2 * 9.81 / 5, "u2": -9.81 / 5}, rel=1e-14)


def _appell_hamel_state():
    run = simulate({"system": "appell-hamel", "model": "linear", "dt": 0.001, "t_final": 3.0, "every": 3000})
    return {k: float(v[-1]) for k, v in run.state.items()}


def test_appell_hamel_linear_and_nonlinear_models_give_the_same_forces_at_a_state():
    """The same motion, the same forces: the linear model's contact force (−λ) and the nonlinear
    model's Appell–Chetaev force (2λ v_o − λ H.y) agree, and the thread tension — λ_thread in
    both — is m (g + u̇5); the contact force is F_c of ẋ, ẏ turned into the heading frame."""
    state = _appell_hamel_state()
    lin = accelerations("appell-hamel", state, variant="linear")
    nl = accelerations("appell-hamel", state, variant="nonlinear")
    assert lin.multipliers != pytest.approx(nl.multipliers)  # other constraints, other λ ...
    for k, v in lin.point_forces.items():  # ... the same forces
        assert nl.point_forces[k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
    assert _rel(list(nl.constraint_forces.values()), list(lin.constraint_forces.values())) < 1e-9
    assert nl.point_forces["thread.tension"] == pytest.approx(1.0 * (9.81 + nl["u5"]), rel=1e-12)
    th = state["theta"]
    fx, fy = nl.constraint_forces["u3"], nl.constraint_forces["u4"]
    assert nl.point_forces["contact.longitudinal"] == pytest.approx(fx * math.cos(th) + fy * math.sin(th), rel=1e-9)
    assert nl.point_forces["contact.lateral"] == pytest.approx(-fx * math.sin(th) + fy * math.cos(th), rel=1e-9)


def test_appell_hamel_runs_of_both_models_report_the_same_forces():
    s = {"system": "appell-hamel", "dt": 0.001, "t_final": 10.0, "every": 100}
    nl, lin = simulate({**s, "model": "nonlinear"}), simulate({**s, "model": "linear"})
    for k in lin.point_forces:
        assert _rel(nl.point_forces[k], lin.point_forces[k]) < 1e-8, k


def test_switched_rows_report_the_equivalent_models_forces():
    """A nonlinear run that starts with the wheel not rolling runs its first rows with the
    linear model (λ of the nonlinear model reported as 0 there): its forces are the linear
    model's, row by row, not zero."""
    s = {"system": "appell-hamel", "initial": {"u2": 0.0}, "dt": 0.005, "t_final": 4.0}
    nl, lin = simulate({**s, "model": "nonlinear"}), simulate({**s, "model": "linear"})
    assert nl.summary["switches"] and nl.multipliers["rolling_speed"][0] == 0.0
    for k in lin.point_forces:
        np.testing.assert_allclose(nl.point_forces[k], lin.point_forces[k], rtol=1e-7, atol=1e-7, err_msg=k)
    assert nl.point_forces["contact.longitudinal"][0] == pytest.approx(1.792)  # the force at the start is there
    assert nl.point_forces["thread.tension"][0] == pytest.approx(9.244)


def test_forces_switched_off_leave_no_point_forces():
    run = simulate({"system": "knife-edge", "t_final": 1.0, "constraint_forces": False})
    assert run.point_forces == {} and run.summary["max_abs_point_force"] == {}
