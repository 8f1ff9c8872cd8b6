"""A large model's functions compiled as C (kernel.native): the same numbers as numba's, found by
the loops through numba's cache, and numba alone when there is no C compiler that works."""

from dataclasses import replace

import numpy as np
import pytest

from nmkane_core import get_system
from nmkane_core.kernel import codegen, native
from nmkane_core.kernel.built import built
from nmkane_core.kernel.loader import compiled_kernel
from nmkane_core.run.registry import register
from nmkane_core.run.simulate import simulate
from tests._helpers import require_compiler

require_compiler()  # CI installs one (.ci/run): nothing may skip there


def _native_module(monkeypatch, name, variant):
    """The system's kernel with its model functions in C (every model counts as large)."""
    monkeypatch.setattr(codegen, "INLINE_TERMS_MAX_STATEMENTS", 0)
    d = built(get_system(name)).derivation(variant)
    source = codegen.generate_source(d)
    assert "NATIVE_SOURCE" in source and "types.ExternalFunction(" in source
    return compiled_kernel(d, source)


def _states(info, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.2, 1.5, (n, 2 * info.n))


def test_c_functions_give_numbas_right_hand_side_diagnostics_and_constraint_terms(monkeypatch):
    system = get_system("appell-hamel")  # square roots, trigonometry, a nonlinear constraint
    plain, info = built(system).kernel("nonlinear")
    assert not hasattr(plain, "NATIVE_TAG")
    mod = _native_module(monkeypatch, "appell-hamel", "nonlinear")
    p = built(system).param_vector("nonlinear", system.resolve_params({}))
    G, G1, G2 = -np.eye(2), -20 * np.eye(1), -100 * np.eye(1)
    xs = _states(info, 6, 1)
    for x in xs:
        want, got = plain.rhs(0.3, x, p, G, G1, G2), mod.rhs(0.3, x, p, G, G1, G2)
        np.testing.assert_allclose(got[0], want[0], rtol=1e-12, atol=1e-12)
        assert got[1] == pytest.approx(want[1], rel=1e-9) and got[2] == pytest.approx(want[2], rel=1e-9)
        for a, b in zip(mod.state_terms(0.3, x, p), plain.state_terms(0.3, x, p), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    ts = np.linspace(0, 1, len(xs))
    E, V = np.empty(len(xs)), np.empty((len(xs), plain.NV))
    E2, V2 = np.empty(len(xs)), np.empty((len(xs), plain.NV))
    plain.diagnostics_rows(ts, xs, p, E, V)
    mod.diagnostics_rows(ts, np.asfortranarray(xs), p, E2, V2)  # rows that are not contiguous
    np.testing.assert_allclose(E2, E, rtol=1e-12)
    np.testing.assert_allclose(V2, V, rtol=1e-12, atol=1e-14)


def test_a_run_through_the_c_functions_follows_the_numba_run(monkeypatch):
    """The loops (fixed-step with a projection, adaptive) call the C functions through numba's
    external symbols; the runs are those of the numba kernel."""
    monkeypatch.setattr(codegen, "INLINE_TERMS_MAX_STATEMENTS", 0)
    system = register(replace(get_system("appell-hamel"), name="appell-hamel-in-c"))
    assert hasattr(built(system).module("linear"), "NATIVE_TAG")
    for extra in ({"projection": "yoon"}, {"integrator": "kutta-merson-adaptive"}):
        settings = {"model": "linear", "t_final": 2.0, **extra}
        got = simulate({"system": system.name, **settings}, progress=False)
        want = simulate({"system": "appell-hamel", **settings}, progress=False)
        assert got.status == want.status == "ok" and got.summary["steps"] == want.summary["steps"]
        # fixed steps: the same numbers to round-off; adaptive steps: round-off moves the step
        # control's times by ~1e-9 s, so the motions are compared at the same times
        np.testing.assert_allclose(got.t, want.t, rtol=0, atol=1e-8)
        for name in want.state:
            np.testing.assert_allclose(got.state[name], np.interp(got.t, want.t, want.state[name]), atol=1e-9)
        np.testing.assert_allclose(got.energy, np.interp(got.t, want.t, want.energy), rtol=1e-9)


def test_a_failing_c_compiler_leaves_the_model_to_numba_with_a_warning(monkeypatch, tmp_path):
    system = get_system("sliding-particle")
    plain, info = built(system).kernel("nonminimal")
    p = built(system).param_vector("nonminimal", system.resolve_params({}))
    monkeypatch.setenv("NMKANE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "false")  # found on the PATH, fails on every file
    monkeypatch.setattr(codegen, "INLINE_TERMS_MAX_STATEMENTS", 0)
    d = built(system).derivation("nonminimal")
    with pytest.warns(RuntimeWarning, match="compiled by numba alone"):
        mod = compiled_kernel(d)
    assert not hasattr(mod, "NATIVE_TAG") and mod is not plain
    G1, G2 = -20 * np.eye(1), -100 * np.eye(1)
    for x in _states(info, 3, 2):
        np.testing.assert_allclose(
            mod.rhs(0.0, x, p, np.zeros((0, 0)), G1, G2)[0],
            plain.rhs(0.0, x, p, np.zeros((0, 0)), G1, G2)[0],
            rtol=1e-13,
        )
    assert not list(tmp_path.rglob("native_*.so"))  # nothing half-built left behind


def test_without_a_c_compiler_every_model_is_numbas(monkeypatch):
    monkeypatch.setenv("NMKANE_NATIVE", "0")
    assert native.compiler() is None
    monkeypatch.setattr(codegen, "INLINE_TERMS_MAX_STATEMENTS", 0)
    d = built(get_system("sliding-particle")).derivation("nonminimal")
    assert "NATIVE_SOURCE" not in codegen.generate_source(d)
