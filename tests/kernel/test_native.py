"""The compiled core and a model's C functions (kernel.core, kernel.native, kernel.cmodel): the
numbers of the numpy reference, arrays checked before C reads them, and a missing or failing C
compiler named in one line."""

import subprocess
import sys

import numpy as np
import pytest

from nmkane_core import get_system
from nmkane_core.kernel import core, native
from nmkane_core.kernel.built import built
from nmkane_core.symbolic.reference import ReferenceKernel
from tests._helpers import require_compiler

require_compiler()  # CI installs one (.ci/run): nothing may skip there


def _states(n_speeds, n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.2, 1.5, (n, 2 * n_speeds))


@pytest.mark.parametrize(
    ("name", "variant"),
    [("appell-hamel", "nonlinear"), ("appell-hamel", "linear"), ("sliding-particle", "nonminimal")],
)
def test_the_compiled_right_hand_side_is_the_reference_one(name, variant):
    system = get_system(name)
    b = built(system)
    mod, info = b.kernel(variant)
    ref = ReferenceKernel(b.derivation(variant))
    p = b.param_vector(variant, system.resolve_params({}))
    G, G1, G2 = -np.eye(mod.MNH), -20 * np.eye(mod.MH), -100 * np.eye(mod.MH)
    for x in _states(info.n, 5, 1):
        got, rc_j2, rc_t = mod.rhs(0.3, x, p, G, G1, G2)
        np.testing.assert_allclose(got, ref.rhs(0.3, x, p, G, G1, G2), rtol=1e-10, atol=1e-12)
        assert 0.0 < rc_j2 <= 1.0 and 0.0 < rc_t <= 1.0
        E, viol = mod.diagnostics(0.3, x, p, np.empty(mod.NV)), np.empty(mod.NV)
        mod.diagnostics(0.3, x, p, viol)
        assert pytest.approx(ref.energy(0.3, x, p), rel=1e-12) == E
        np.testing.assert_allclose(viol, ref.violation(0.3, x, p), rtol=1e-12, atol=1e-14)


def test_arrays_the_core_would_misread_are_refused_naming_the_argument():
    system = get_system("sliding-particle")
    mod = built(system).module("nonminimal")
    p = built(system).param_vector("nonminimal", system.resolve_params({}))
    G1, G2 = -np.eye(1), -np.eye(1)
    x = np.ones(2 * mod.N)
    with pytest.raises(TypeError, match="x: a C-contiguous float64 array"):
        mod.rhs_ws(
            0.0, x.astype(np.float32), p, np.zeros((0, 0)), G1, G2, np.empty((1, x.size)), 0, mod.make_workspace()
        )
    with pytest.raises(ValueError, match="x: shape"):
        mod.rhs(0.0, np.ones(3), p, np.zeros((0, 0)), G1, G2)
    with pytest.raises(ValueError, match="G1: shape"):
        mod.rhs(0.0, x, p, np.zeros((0, 0)), -np.eye(2), G2)
    with pytest.raises(ValueError, match="p: 0 values"):
        mod.rhs(0.0, x, np.zeros(0), np.zeros((0, 0)), G1, G2)
    E, V = np.empty(3), np.empty((3, mod.NV))
    with pytest.raises(TypeError, match="xs: a C-contiguous"):
        mod.diagnostics_rows(np.zeros(3), np.asfortranarray(np.ones((3, 2 * mod.N))), p, E, V)


def _fresh_process(code: str, env: dict) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300)


def test_a_failing_c_compiler_is_named_in_one_line_and_leaves_nothing_half_built(tmp_path):
    import os

    env = {**os.environ, "NMKANE_CACHE_DIR": str(tmp_path), "CC": "false"}  # on the PATH, fails on every file
    out = subprocess.run(
        [sys.executable, "-m", "nmkane_core.cli", "run", "sliding-particle", "--t-final", "0.1"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert out.returncode != 0
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "false failed on" in lines[0] and "Traceback" not in out.stderr, out.stderr
    assert not list(tmp_path.rglob("*.so")) and not list(tmp_path.rglob("build_*"))


def test_without_a_c_compiler_the_error_says_what_to_install(monkeypatch):
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert native.compiler() is None
    with pytest.raises(native.NativeBuildError, match="apt install gcc"):
        native.compiler_or_fail()


def test_the_core_is_one_library_for_every_model_and_its_header_is_generated_from_the_tables():
    """The records the C side reads are generated from kernel.interface's tables: every work-array
    block and every loop argument is a field of the generated header, and the ctypes twins have the
    same fields in the same order."""
    from nmkane_core.kernel.interface import PROJECTION_SCRATCH, WORKSPACE

    text = core.header()
    for name, _, _ in (*WORKSPACE, *PROJECTION_SCRATCH):
        assert f"i64 {name};" in text
    assert [f for f, _ in core.ModelRecord._fields_][: len(core.MODEL_INTS)] == list(core.MODEL_INTS)
    a = built(get_system("sliding-particle")).module("nonminimal")
    b = built(get_system("appell-hamel")).module("nonlinear")
    assert a._generic is b._generic is core.library()


@pytest.mark.parametrize(
    "settings",
    [
        {"system": "appell-hamel", "t_final": 2.0, "dt": 0.001, "projection": "yoon"},
        {"system": "iftomm-a02", "t_final": 2.0, "integrator": "kutta-merson-adaptive", "projection": "yoon"},
        {"system": "rattleback", "t_final": 1.0},  # its C varies: the kinematics' estimate, inlined
    ],
)
def test_the_specialised_build_gives_the_generic_cores_bits(settings, monkeypatch):
    """kernel.special compiles the same source with the model's sizes constant and its functions
    inlined, at -O3: no reassociation, no contraction, so every number is the generic core's."""
    from nmkane_core.run.plan import resolve
    from nmkane_core.run.simulate import simulate

    plan = resolve(settings)
    mod = built(plan.system).module(plan.variant)
    mod.specialize(wait=True)
    assert mod.specialized
    special = simulate(plan, progress=False)
    monkeypatch.setattr(mod, "_core", mod._generic)
    generic = simulate(plan, progress=False)
    assert special.status == generic.status == "ok"
    for name in generic.state:
        assert np.array_equal(special.state[name], generic.state[name]), name
    assert np.array_equal(special.energy, generic.energy)
    assert special.summary["min_rcond"] == generic.summary["min_rcond"]
