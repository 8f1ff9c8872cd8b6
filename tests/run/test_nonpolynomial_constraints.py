"""Nonholonomic constraints of any smooth form in the speeds — square roots, trigonometric,
rational and exponential functions of u — through the whole pipeline: declaration,
derivation, generated kernels, runs, the singularity monitor and initial-state completion.

Every trajectory is checked against a reference that shares nothing with nmkane but the
equations' physics: a closed form, or a hand-written Gauss-principle ODE (all derivatives
written out by hand in numpy)

    M u̇ = F + Jᵀλ,   J u̇ = −(∂φ/∂q) q̇ + Γφ,   q̇ = u,

solved for (u̇, λ) at every call and integrated by scipy's ``solve_ivp`` at rtol 1e-11.  The
nonminimal Kane equations A2(Q u̇ − P) = 0 with A2ᵀ spanning the null space of J say the
same thing (Q u̇ − P lies in the range of Jᵀ), so the two must agree to the tolerances.

Systems (registered for this module only):

* ``np-speed``  particle in a vertical plane under gravity driven at constant speed:
  φ = √(u1² + u2²) − v (the speed along the path), u_D = u1.  Closed form: the velocity
  u = v(cos θ, sin θ) turns by θ̇ = −(g/v) cos θ, so θ = gd(s) with s = s0 − g t / v,
  u1 = v / cosh s, u2 = v tanh s, x = x0 + (v²/g)(θ0 − θ), y = y0 + (v²/g) ln(cosh s0 / cosh s).
* ``np-branch`` the same motion written with the branch u2 = +√(a² − u1²):
  φ = u2 − √(a² − u1²), u_D = u2.  The branch ends at t* = a s0 / g, where u2 = 0 and the
  square root's argument reaches zero: the run must stop there with a status and a message.
* ``np-cone``, ``np-trig``, ``np-rational``, ``np-exp``: a particle in space on springs
  under gravity with φ = u3 − f(q, u1, u2) for f a square root (homogeneous: the constraint
  does no work, the energy is conserved), trigonometric, rational and exponential in the
  speeds.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from nmkane_core import Parameter, System, register, simulate
from nmkane_core.kernel.built import built
from nmkane_core.run.simulate import kernel_for

RTOL_REF = 1e-11


# --------------------------------------------------------------------------- models (sympy inside)
def _plane_speed():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    m, g, v = sp.symbols("m g v", positive=True)
    return MechanicalModel(
        q=(x, y),
        u=(u1, u2),
        params=(m, g, v),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, -m * g]),
        nonholonomic={"speed": sp.sqrt(u1**2 + u2**2) - v},
        u_independent=(u2,),
        energy=m / 2 * (u1**2 + u2**2),
    )  # kinetic energy: constant


def _plane_branch():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y = plain_symbols("x y")
    u1, u2 = plain_symbols("u1 u2")
    m, g, a = sp.symbols("m g a", positive=True)
    return MechanicalModel(
        q=(x, y),
        u=(u1, u2),
        params=(m, g, a),
        C=sp.eye(2),
        D=sp.zeros(2, 1),
        Q=m * sp.eye(2),
        P=sp.Matrix([0, -m * g]),
        nonholonomic={"branch": u2 - sp.sqrt(a**2 - u1**2)},
        u_independent=(u1,),
        energy=m / 2 * (u1**2 + u2**2),
    )


def _space(form: str):
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, z = plain_symbols("x y z")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, k, g, c = sp.symbols("m k g c", positive=True)
    f = {
        "cone": c * sp.sqrt(u1**2 + u2**2),
        "trig": c * sp.sin(u1) * sp.cos(y),
        "rational": c * u1 / (1 + u1**2 + u2**2) + c * x * u2,
        "exp": c * sp.exp(-(x**2)) * (sp.exp(u1) - 1),
    }[form]
    kz = 0 if form == "cone" else k  # the cone: no vertical spring (see FORM_PARAMS)
    return MechanicalModel(
        q=(x, y, z),
        u=(u1, u2, u3),
        params=(m, k, g, c),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=m * sp.eye(3),
        P=sp.Matrix([-k * x, -k * y, -kz * z - m * g]),
        nonholonomic={form: u3 - f},
        u_independent=(u1, u2),
        energy=m / 2 * (u1**2 + u2**2 + u3**2) + k / 2 * (x**2 + y**2) + kz / 2 * z**2 + m * g * z,
    )


def _space_cone():
    return _space("cone")


def _space_trig():
    return _space("trig")


def _space_rational():
    return _space("rational")


def _space_exp():
    return _space("exp")


FORMS = {"cone": _space_cone, "trig": _space_trig, "rational": _space_rational, "exp": _space_exp}
SPACE_PARAMS = {"m": 1.3, "k": 2.0, "g": 9.81, "c": 0.7}
# the cone without gravity or vertical spring: u3 = c|u_h| ≥ 0 always, so a downward force would drive |u_h|
# to the kink at 0; without one, the angular momentum L = x u2 − y u1 obeys L |u_h|^(c²) = const, keeping
# |u_h| away from 0
FORM_PARAMS = {form: dict(SPACE_PARAMS, g=0.0) if form == "cone" else SPACE_PARAMS for form in FORMS}
SPACE_INIT = {"x": 0.4, "y": -0.2, "z": 0.1, "u1": 0.9, "u2": 0.6}


def _systems():
    par = lambda v, unit="": Parameter(v, 0.0, 1e3, unit, min_inclusive=True)  # noqa: E731
    out = [
        System(
            name="np-speed",
            variants=_plane_speed,
            title="speed along a path (test)",
            parameters={"m": par(1.0, "kg"), "g": par(0.5, "m/s²"), "v": par(1.0, "m/s")},
            # u1 = 1 is the guess that picks the branch u1 > 0 (x, y left out: 0, and not a full state)
            default_initial={"u2": 0.5 * math.sqrt(3), "u1": 1.0},
            default_dt=0.001,
            default_t_final=4.0,
        ),
        System(
            name="np-branch",
            variants=_plane_branch,
            title="end of a square root's branch (test)",
            parameters={"m": par(1.0, "kg"), "g": par(1.0, "m/s²"), "a": par(1.0, "m/s")},
            default_initial={"x": 0.0, "y": 0.0, "u1": 0.5},
            default_dt=0.001,
            default_t_final=1.0,
        ),
    ]
    for form, factory in FORMS.items():
        out.append(
            System(
                name=f"np-{form}",
                variants=factory,
                title=f"{form} constraint in the speeds (test)",
                parameters={k: par(v) for k, v in FORM_PARAMS[form].items()},
                default_initial=dict(SPACE_INIT),
                default_dt=0.001,
                default_t_final=3.0,
            )
        )
    return out


@pytest.fixture(autouse=True, scope="module")
def registered():
    """Registered for this module's tests only (the registry is process-wide)."""
    from nmkane_core.run.registry import unregister

    systems = _systems()
    for s in systems:
        register(s)
    yield
    for s in systems:
        unregister(s.name)


# --------------------------------------------------------------------------- independent references
def _gd(s):
    return np.arctan(np.sinh(s))


def _speed_closed_form(t, v, g, theta0, x0=0.0, y0=0.0):
    s0 = math.asinh(math.tan(theta0))
    s = s0 - g * t / v
    th = _gd(s)
    return {
        "u1": v / np.cosh(s),
        "u2": v * np.tanh(s),
        "x": x0 + v * v / g * (theta0 - th),
        "y": y0 + v * v / g * (np.log(np.cosh(s0)) - np.log(np.cosh(s))),
    }


def _space_functions(form, p):
    """φ, ∂φ/∂u, ∂φ/∂q of φ = u3 − f(q, u1, u2), written out by hand."""
    c = p["c"]

    def parts(q, u):
        x, y, _ = q
        u1, u2, u3 = u
        if form == "cone":
            r = math.hypot(u1, u2)
            f, fu, fq = c * r, (c * u1 / r, c * u2 / r), (0.0, 0.0, 0.0)
        elif form == "trig":
            f = c * math.sin(u1) * math.cos(y)
            fu, fq = (c * math.cos(u1) * math.cos(y), 0.0), (0.0, -c * math.sin(u1) * math.sin(y), 0.0)
        elif form == "rational":
            d = 1 + u1 * u1 + u2 * u2
            f = c * u1 / d + c * x * u2
            fu = (c * (d - 2 * u1 * u1) / d**2, -2 * c * u1 * u2 / d**2 + c * x)
            fq = (c * u2, 0.0, 0.0)
        else:
            e = math.exp(-x * x)
            f = c * e * (math.exp(u1) - 1)
            fu, fq = (c * e * math.exp(u1), 0.0), (-2 * x * c * e * (math.exp(u1) - 1), 0.0, 0.0)
        phi = u3 - f
        J = np.array([-fu[0], -fu[1], 1.0])
        Jq = -np.array(fq)
        return phi, J, Jq

    return parts


def _gauss_reference(parts, mass, force, x0, t_eval, gamma=0.0):
    """Integrate M u̇ = F + Jᵀλ, J u̇ = −Jq q̇ + Γφ, q̇ = u (one constraint) with solve_ivp."""
    n = len(x0) // 2

    def f(t, x):
        q, u = x[:n], x[n:]
        phi, J, Jq = parts(q, u)
        K = np.zeros((n + 1, n + 1))
        K[:n, :n] = mass
        K[:n, n] = -J
        K[n, :n] = J
        rhs = np.concatenate([force(q, u), [-Jq @ u + gamma * phi]])
        sol = np.linalg.solve(K, rhs)
        return np.concatenate([u, sol[:n]])

    out = solve_ivp(f, (0.0, t_eval[-1]), x0, method="DOP853", t_eval=t_eval, rtol=RTOL_REF, atol=1e-12)
    assert out.status == 0, out.message
    return out.y.T


def _space_reference(form, run, gamma=0.0):
    p = run.settings["params"]
    names = ("x", "y", "z", "u1", "u2", "u3")
    x0 = np.array([run.state[k][0] for k in names])
    mass = p["m"] * np.eye(3)

    def force(q, u):
        kz = 0.0 if form == "cone" else p["k"]
        return np.array([-p["k"] * q[0], -p["k"] * q[1], -kz * q[2] - p["m"] * p["g"]])

    return _gauss_reference(_space_functions(form, p), mass, force, x0, run.t, gamma), names


# --------------------------------------------------------------------------- trajectories
def test_sqrt_speed_constraint_follows_the_closed_form():
    th0 = math.pi / 3
    run = simulate(
        {
            "system": "np-speed",
            "integrator": "kutta-merson-adaptive",
            "rtol": 1e-11,
            "atol": 1e-12,
            "t_final": 4.0,
            "initial": {"u2": math.sin(th0)},
        },
        progress=False,
    )
    assert run.status == "ok", run.summary["message"]
    assert abs(run.state["u1"][0] - math.cos(th0)) < 1e-12  # completed on the branch u1 > 0
    want = _speed_closed_form(run.t, 1.0, 0.5, th0)
    assert run.state["u2"][-1] < -0.3  # the velocity turned past horizontal
    for k, ref in want.items():
        np.testing.assert_allclose(run.state[k], ref, atol=1e-8, err_msg=k)
    assert run.summary["max_abs_energy_drift"] < 1e-9  # the speed, hence T, is constant
    assert run.summary["max_abs_violation"]["speed"] < 1e-9


def test_sqrt_speed_constraint_fixed_step_with_and_without_gamma():
    th0 = math.pi / 3
    base = {"system": "np-speed", "integrator": "rk4", "dt": 0.01, "t_final": 4.0, "initial": {"u2": math.sin(th0)}}
    for gamma in (0.0, -5.0):
        run = simulate({**base, "gamma": gamma}, progress=False)
        assert run.status == "ok", run.summary["message"]
        for k, ref in _speed_closed_form(run.t, 1.0, 0.5, th0).items():
            np.testing.assert_allclose(run.state[k], ref, atol=1e-7, err_msg=f"{k}, Γ = {gamma}")
        assert run.summary["max_abs_violation"]["speed"] < 1e-8


@pytest.mark.parametrize("form", list(FORMS))
def test_nonpolynomial_constraint_matches_the_gauss_principle_reference(form):
    run = simulate(
        {"system": f"np-{form}", "integrator": "kutta-merson-adaptive", "rtol": 1e-11, "atol": 1e-12}, progress=False
    )
    assert run.status == "ok", run.summary["message"]
    ref, names = _space_reference(form, run)
    got = np.column_stack([run.state[k] for k in names])
    scale = np.abs(ref).max(axis=0)
    np.testing.assert_allclose(got, ref, atol=1e-8 * max(1.0, scale.max()), err_msg=form)
    assert np.ptp(ref[:, 5]) > 0.3  # a motion that exercises u3 = f(u)
    assert run.summary["max_abs_violation"][form] < 1e-9
    if form == "cone":
        # φ is homogeneous of degree 1 in u: Jᵀλ·u = λφ = 0, the constraint does no work
        assert run.summary["max_abs_energy_drift"] < 1e-8


@pytest.mark.parametrize("form", ["trig", "exp"])
def test_nonpolynomial_constraint_with_gamma_matches_the_reference_with_gamma(form):
    run = simulate({"system": f"np-{form}", "integrator": "rk4", "dt": 0.01, "gamma": -5.0}, progress=False)
    assert run.status == "ok", run.summary["message"]
    ref, names = _space_reference(form, run, gamma=-5.0)
    got = np.column_stack([run.state[k] for k in names])
    np.testing.assert_allclose(got, ref, atol=1e-6, err_msg=form)


@pytest.mark.parametrize("form", ["trig", "exp"])
def test_nonpolynomial_constraint_drift_stays_without_gamma_and_is_pulled_back_with_it(form):
    # RK4 at a coarse step for a minute: without Γ the truncation errors of φ stay (φ̇ = 0 is all
    # the equations know) and accumulate; with Γ = −5 the error dynamics φ̇ = Γφ (the paper's
    # (104)) pull them back
    base = {"system": f"np-{form}", "integrator": "rk4", "dt": 0.02, "t_final": 60.0}
    free = simulate(base, progress=False)
    held = simulate({**base, "gamma": -5.0}, progress=False)
    assert free.status == held.status == "ok"
    v_free, v_held = np.abs(free.violation[form]), np.abs(held.violation[form])
    tenth = len(v_free) // 10
    assert v_free[-tenth:].max() >= 0.5 * v_free[:tenth].max() > 1e-9  # not pulled back
    assert v_held[-tenth:].max() < v_free[-tenth:].max() / 100  # pulled back
    assert held.summary["max_abs_violation"][form] < 1e-4


def test_compiled_rhs_of_nonpolynomial_constraints_agrees_with_reference_kernel():
    from nmkane_core import get_system
    from nmkane_core.symbolic.reference import ReferenceKernel

    rng = np.random.default_rng(5)
    G, empty = np.array([[-2.0]]), np.zeros((0, 0))
    for form in FORMS:
        system = get_system(f"np-{form}")
        mod = kernel_for(system, None)
        ref = ReferenceKernel(built(system).derivation())
        for _ in range(10):
            x = rng.uniform(-1.0, 1.0, 6)
            p = rng.uniform(0.5, 2.0, 4)
            got, rc, _ = mod.rhs(0.0, x, p, G, empty, empty)
            want = ref.rhs(0.0, x, p, G, empty, empty)
            np.testing.assert_allclose(got, want, rtol=1e-11, atol=1e-11 * np.abs(want).max(), err_msg=form)
            assert rc == pytest.approx(ref.matrices(0.0, x, p, G)["rcond_J2"], rel=1e-12)


# --------------------------------------------------------------------------- the singularity monitor
def test_monitor_of_a_nonpolynomial_row_is_scale_free_and_sees_the_gradient_turn_away():
    # φ = u2 − √(a² − u1²): J = [u1/√(a² − u1²), 1], a 1×1 J2 = 1 whose pivot ratio is always
    # 1; the estimate is the share of the row's gradient on u_D: min(1, √(a² − u1²)/|u1|)
    from nmkane_core import get_system

    mod = kernel_for(get_system("np-branch"), None)
    G, empty = np.zeros((1, 1)), np.zeros((0, 0))
    for a in (0.01, 1.0, 100.0):  # speeds of any size
        for frac in (0.3, 0.9, 0.999, 1 - 1e-9):
            u1 = frac * a
            x = np.array([0.0, 0.0, u1, math.sqrt(a * a - u1 * u1)])
            _, rc, _ = mod.rhs(0.0, x, np.array([1.0, 1.0, a]), G, empty, empty)
            want = min(1.0, math.sqrt(1 - frac * frac) / frac)
            assert rc == pytest.approx(want, rel=1e-6), (a, frac)
        for u1 in (a, 1.5 * a):  # the branch's end (√0, 1/0) and past it (√ of u < 0):
            xd, _, _ = mod.rhs(0.0, np.array([0.0, 0.0, u1, 0.0]), np.array([1.0, 1.0, a]), G, empty, empty)
            assert not np.all(np.isfinite(xd))  # no exception from compiled code: ±inf/NaN, which
            # the loops' finiteness checks turn into a status


def test_sqrt_branch_follows_the_closed_form_before_its_end():
    run = simulate(
        {"system": "np-branch", "integrator": "kutta-merson-adaptive", "rtol": 1e-11, "atol": 1e-12, "t_final": 1.0},
        progress=False,
    )
    assert run.status == "ok", run.summary["message"]
    want = _speed_closed_form(run.t, 1.0, 1.0, math.pi / 3)
    for k, ref in want.items():
        np.testing.assert_allclose(run.state[k], ref, atol=1e-8, err_msg=k)


T_STAR = math.asinh(math.sqrt(3.0))  # a s0 / g: where u2 = √(a² − u1²) reaches 0


@pytest.mark.parametrize("integrator", ["rk4", "kutta-merson", "kutta-merson-adaptive", "rk45", "dop853", "radau"])
def test_end_of_a_square_roots_branch_is_reported_not_integrated(integrator):
    settings = {"system": "np-branch", "integrator": integrator, "dt": 0.001, "t_final": 3.0}
    run = simulate(settings, progress=False, time_limit=60)
    s = run.summary
    assert run.status in ("singular", "diverged", "drifted", "failed"), s["message"]
    assert run.status != "failed" or "cannot be continued" in s["message"] or "max_rows" in s["message"], s
    assert T_STAR - 0.05 < s["t_end"] < T_STAR + 0.01, s
    arrays = [run.t, run.energy, *run.state.values(), *run.violation.values()]
    assert all(np.all(np.isfinite(a)) for a in arrays)  # never NaN presented as a result
    assert all(math.isfinite(v) for v in s["max_abs_violation"].values())
    assert len(run.t) < 1e5  # bounded output
    good = run.t < T_STAR - 0.05
    want = _speed_closed_form(run.t[good], 1.0, 1.0, math.pi / 3)
    np.testing.assert_allclose(run.state["u1"][good], want["u1"], atol=1e-5)
    run.document()  # a valid run document


def test_end_of_a_square_roots_branch_with_projection_and_gamma():
    run = simulate(
        {"system": "np-branch", "dt": 0.01, "t_final": 3.0, "gamma": -10.0, "projection": "blajer"},
        progress=False,
        time_limit=60,
    )
    assert run.status in ("singular", "diverged", "drifted", "failed"), run.summary["message"]
    assert run.summary["t_end"] < T_STAR + 0.02
    assert all(np.all(np.isfinite(v)) for v in run.state.values())


# --------------------------------------------------------------------------- initial states
def test_completion_from_a_guess_on_the_singular_point_of_a_square_root():
    # np-speed's default guess u1 = 1 picks the branch; with u1 = 0 as the starting guess
    # (∂φ/∂u1 = u1/|u| = 0 there) completion still finds the branch u1 > 0
    from nmkane_core import get_system
    from nmkane_core.run.initial import complete_state

    system = get_system("np-speed")
    mod, info = built(system).kernel(None)
    p = built(system).param_vector("default", {"m": 1.0, "g": 0.5, "v": 1.0})
    x = np.array([0.0, 0.0, 0.0, 0.6])
    xc = complete_state(mod, info, x, p)
    assert xc[2] == pytest.approx(0.8, abs=1e-12)


def test_completion_that_cannot_succeed_says_what_to_change():
    from nmkane_core.errors import InputError

    with pytest.raises(InputError) as e:  # |u2| > v: no real u1
        simulate({"system": "np-speed", "initial": {"u2": 1.5}, "t_final": 0.1}, progress=False)
    text = str(e.value)
    assert "u2" in text and "1.5" in text and "speed" in text, text
