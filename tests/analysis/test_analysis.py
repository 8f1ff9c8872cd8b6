"""accelerations() and linearize(): any system, at a state, against closed forms."""

import math

import numpy as np
import pytest

from nmkane_core import InconsistentStateError, InputError, accelerations, linearize
from nmkane_core.run.initial import default_state


def _particle_state(x, xdot, l0=1.0):
    # on the parabola y = l0 − x²/l0, so u2 = ẏ = −2 x ẋ / l0
    return {"x": x, "y": l0 - x * x / l0, "u1": xdot, "u2": -2 * x * xdot / l0}


@pytest.mark.parametrize("x,xdot,l0", [(0.5, 0.3, 1.0), (-1.2, 2.0, 2.0), (0.0, 0.0, 1.0)])
def test_particle_accelerations_match_the_lagrangian_closed_form(x, xdot, l0):
    """L = m/2 ẋ²(1 + 4x²/l0²) + m g (l0 − x²/l0) ⇒ ẍ = −(4xẋ²/l0² + 2gx/l0)/(1 + 4x²/l0²)."""
    g = 9.81
    acc = accelerations("sliding-particle", _particle_state(x, xdot, l0), params={"l0": l0})
    expected = -(4 * x * xdot**2 / l0**2 + 2 * g * x / l0) / (1 + 4 * x**2 / l0**2)
    assert acc["u1"] == pytest.approx(expected, rel=1e-12, abs=1e-12)
    # ÿ = d/dt(−2xẋ/l0) = −2(ẋ² + x ẍ)/l0
    assert acc["u2"] == pytest.approx(-2 * (xdot**2 + x * expected) / l0, rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("l0", [0.5, 1.0, 3.0])
def test_particle_linearization_oscillates_at_sqrt_2g_over_l0(l0):
    lin = linearize("sliding-particle", _particle_state(0.0, 0.0, l0), params={"l0": l0})
    assert lin.names == ("x", "u1")
    omega = math.sqrt(2 * 9.81 / l0)
    ev = sorted(lin.eigenvalues, key=lambda v: v.imag)
    assert abs(ev[0].real) < 1e-9 and abs(ev[1].real) < 1e-9
    assert ev[1].imag == pytest.approx(omega, rel=1e-9) and ev[0].imag == pytest.approx(-omega, rel=1e-9)


def test_minimal_formulation_linearizes_to_the_same_frequency():
    lin = linearize("sliding-particle", {"x": 0.0, "u1": 0.0}, variant="minimal")
    assert sorted(abs(v.imag) for v in lin.eigenvalues)[-1] == pytest.approx(math.sqrt(2 * 9.81), rel=1e-9)


def test_an_inconsistent_state_is_refused_with_the_constraint_named():
    with pytest.raises(InconsistentStateError) as e:
        accelerations("sliding-particle", {"x": 0.5, "y": 0.0, "u1": 0.0, "u2": 0.0})
    assert "surface" in str(e.value)


def test_missing_and_unknown_names_are_refused():
    with pytest.raises(InputError, match="missing"):
        accelerations("sliding-particle", {"x": 0.0})
    with pytest.raises(InputError, match="unknown state name"):
        accelerations("sliding-particle", {**_particle_state(0, 0), "z": 1.0})
    with pytest.raises(InputError, match="not independent"):
        linearize("sliding-particle", _particle_state(0, 0), keep=["y"])


def test_appell_hamel_linearization_keeps_what_is_asked():
    from nmkane_core import get_system

    s = get_system("appell-hamel")
    lin = linearize(s, default_state(s), keep=["theta", "u1", "u2"])
    assert lin.A.shape == (3, 3) and np.all(np.isfinite(lin.A))
    assert lin.A[0].tolist() == pytest.approx([0.0, 1.0, 0.0], abs=1e-8)  # θ̇ = u1
