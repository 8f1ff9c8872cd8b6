"""A user's own system, registered through the public API, gets the whole pipeline:
derivation, generated and compiled kernels (checked against the numpy reference), runs
checked against a closed-form solution, and singularity detection.

The knife edge (a Chaplygin-sleigh-like blade on the plane): q = (x, y, θ), u = (ẋ, ẏ, θ̇),
mass m, inertia I, no forces; the nonholonomic constraint φ = −sinθ·u1 + cosθ·u2 = 0 (no
sideways slip), u_I = (u1, u3), u_D = u2 (J2 = cosθ, singular at θ = ±π/2).  From rest
in x with ẋ = v and θ̇ = ω the blade runs along a circle: θ = ωt, x = (v/ω) sin ωt,
y = (v/ω)(1 − cos ωt), speed v and energy constant.
"""

import numpy as np
import pytest

from nmkane_core import Parameter, System, register, simulate
from nmkane_core.kernel.built import built
from nmkane_core.run.simulate import kernel_for
from nmkane_core.symbolic.reference import ReferenceKernel

NAME = "test-knife-edge"


def _knife_edge():
    import sympy as sp

    from nmkane_core import MechanicalModel, plain_symbols

    x, y, th = plain_symbols("x y theta")
    u1, u2, u3 = plain_symbols("u1 u2 u3")
    m, inertia = sp.symbols("m I", real=True)
    return MechanicalModel(
        name="nonminimal",
        q=(x, y, th),
        u=(u1, u2, u3),
        params=(m, inertia),
        C=sp.eye(3),
        D=sp.zeros(3, 1),
        Q=sp.diag(m, m, inertia),
        P=sp.zeros(3, 1),
        nonholonomic={"no_side_slip": -sp.sin(th) * u1 + sp.cos(th) * u2},
        u_independent=(u1, u3),
        energy=m / 2 * (u1**2 + u2**2) + inertia / 2 * u3**2,
    )


def knife_edge() -> System:
    return System(
        name=NAME,
        title="Knife edge on the plane (test)",
        variants=_knife_edge,
        parameters={"m": Parameter(1.0, 0.0, 1e3, "kg"), "I": Parameter(0.5, 0.0, 1e3, "kg m²")},
        default_initial={"x": 0.0, "y": 0.0, "theta": 0.0, "u1": 1.0, "u3": 1.0},
        default_dt=0.001,
        default_t_final=1.2,
    )


@pytest.fixture(autouse=True, scope="module")
def registered():
    """Registered for this module's tests only (the registry is process-wide)."""
    from nmkane_core.run.registry import unregister

    register(knife_edge())
    yield
    unregister(NAME)


def test_user_system_compiled_rhs_agrees_with_reference():
    from nmkane_core import get_system

    system = get_system(NAME)
    mod = kernel_for(system, None)
    ref = ReferenceKernel(built(system).derivation())
    rng = np.random.default_rng(11)
    G = np.array([[-3.0]])
    empty = np.zeros((0, 0))
    for _ in range(30):
        x = rng.uniform(-1.2, 1.2, 6)
        p = rng.uniform(0.5, 2.0, 2)
        got, rc_j2, _ = mod.rhs(0.0, x, p, G, empty, empty)
        want = ref.rhs(0.0, x, p, G, empty, empty)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
        # a 1×1 J2 = cos θ; auto (the default) measures it in the row equilibrated over [J1 J2]
        c, s = abs(np.cos(x[2])), abs(np.sin(x[2]))
        assert rc_j2 == pytest.approx(c / max(c, s), rel=1e-12)


@pytest.mark.parametrize("integrator", ["rk4", "kutta-merson", "kutta-merson-adaptive", "dop853"])
def test_user_system_follows_the_closed_form_circle(integrator):
    v, w, t_end = 1.0, 1.0, 1.2
    settings = {"system": NAME, "integrator": integrator, "dt": 0.001, "t_final": t_end, "initial": {"u1": v, "u3": w}}
    if integrator in ("kutta-merson-adaptive", "dop853"):
        settings.update(rtol=1e-11, atol=1e-11)
    run = simulate(settings, progress=False)
    assert run.status == "ok", run.summary["message"]
    t = run.t
    np.testing.assert_allclose(run.state["theta"], w * t, atol=1e-9)
    np.testing.assert_allclose(run.state["x"], v / w * np.sin(w * t), atol=1e-8)
    np.testing.assert_allclose(run.state["y"], v / w * (1 - np.cos(w * t)), atol=1e-8)
    assert run.summary["max_abs_energy_drift"] < 1e-8
    assert run.summary["max_abs_violation"]["no_side_slip"] < 1e-9


def test_user_system_singular_constraint_jacobian_is_reported_not_integrated():
    # θ̇ = π/2: θ reaches π/2 on the step ending at t = 1 s, where J2 = cos θ vanishes (to
    # round-off).  The paper's solve stops there, says why, and keeps the good part; the default
    # (auto) solves for u1 there instead, says so in the switches, and stays on the exact motion
    req = {"system": NAME, "dt": 0.001, "t_final": 3.0, "initial": {"u3": np.pi / 2}}
    run = simulate({**req, "solve": "paper"}, progress=False)
    assert run.status == "singular", run.summary["message"]
    assert 0.99 <= run.summary["t_end"] <= 1.0
    assert np.all(np.isfinite(run.state["u2"]))
    np.testing.assert_allclose(run.state["x"], 2 / np.pi * np.sin(np.pi / 2 * run.t), atol=1e-9)
    auto = simulate(req, progress=False)
    assert auto.status == "ok", auto.summary["message"]
    first = auto.summary["switches"][0]
    assert 0.9 < first["t"] <= 1.0 and first["to"] == "partition u_I = (u3, u2)", first
    np.testing.assert_allclose(auto.state["x"], 2 / np.pi * np.sin(np.pi / 2 * auto.t), atol=1e-9)


def test_user_system_passes_near_the_singularity_accurately_and_reports_how_near():
    # with θ̇ = 1 no stage lands within the threshold of θ = π/2: the dependent speed's
    # coordinate singularity is crossed, the motion stays exact, and the summary reports
    # how ill-conditioned the crossing was (the reduced system's rcond)
    run = simulate({"system": NAME, "dt": 0.001, "t_final": 3.0}, progress=False)
    if run.status == "ok":
        np.testing.assert_allclose(run.state["x"], np.sin(run.t), atol=1e-9)
        assert run.summary["min_rcond"]["T"] < 1e-4
    else:
        assert run.status == "singular" and 1.5 < run.summary["t_end"] < 1.58


def test_public_simulate_is_the_function_whatever_was_imported_first():
    import subprocess
    import sys

    code = (
        "import nmkane_core.run.simulate\n"
        "from nmkane_core.run.simulate import kernel_for\n"
        "from nmkane_core import simulate, simulate_many, resolve\n"
        "import nmkane_core, sys\n"
        "assert callable(simulate) and simulate.__name__ == 'simulate', simulate\n"
        "assert nmkane_core.simulate is simulate and callable(nmkane_core.simulate)\n"
        "assert 'sympy' not in sys.modules\n"
        "print(simulate({'system': 'sliding-particle', 't_final': 0.1}).status)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"
