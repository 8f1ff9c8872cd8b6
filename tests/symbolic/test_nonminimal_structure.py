"""Structure the paper proves (Section 2.4): A1 A2ᵀ = 0 and T invertible at consistent states."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from nmkane_core import get_system
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import initial_state
from nmkane_core.symbolic.reference import ReferenceKernel

_REF = {}


def _ref(variant):
    if variant not in _REF:
        _REF[variant] = ReferenceKernel(built(get_system("appell-hamel")).derivation(variant))
    return _REF[variant]


speeds = st.floats(-5, 5).filter(lambda v: abs(v) > 1e-2)


@settings(max_examples=60, deadline=None)
@given(
    theta=st.floats(-np.pi, np.pi),
    u1=st.floats(-5, 5),
    u2=speeds,
    variant=st.sampled_from(["nonlinear", "linear"]),
    rho=st.floats(0.5, 10),
    a=st.floats(0.2, 3),
    b=st.floats(0.1, 2),
)
def test_A1_A2T_is_zero_and_T_invertible_at_consistent_states(theta, u1, u2, variant, rho, a, b):
    system = get_system("appell-hamel")
    params = system.resolve_params({"rho": rho, "a": a, "b": b})
    x0, _ = initial_state(system, variant, params, {"theta": theta, "u1": u1, "u2": u2})
    p = np.array([params[k] for k in system.param_names])
    mats = _ref(variant).matrices(0.0, x0, p)
    A1, A2, T = mats["A1"], mats["A2"], mats["T"]
    scale = 1 + np.abs(A1).max() * np.abs(A2).max()
    assert np.abs(A1 @ A2.T).max() <= 1e-12 * scale
    assert np.linalg.matrix_rank(A1) == 3 and np.linalg.matrix_rank(A2) == 2
    assert np.linalg.cond(T) < 1e10
