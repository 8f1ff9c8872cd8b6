"""Code generation: the exact rewrites applied before printing, the source-level inlining,
and compiled functions that must stay compiled once (numba specialises on literals)."""

import re

import numpy as np
import pytest
import sympy as sp

from nmkane_core import get_system
from nmkane_core.kernel.built import built
from nmkane_core.kernel.codegen import generate_source
from nmkane_core.kernel.inline import inline_marked
from nmkane_core.kernel.interface import AdaptiveArgs, FixedArgs, loop_signature
from nmkane_core.run.simulate import kernel_for, simulate
from nmkane_core.symbolic.terms import kernel_terms, pythagorean

a, b, c, x, y = sp.symbols("a b c x y", real=True)


@pytest.mark.parametrize(
    "expr,want",
    [
        (sp.sin(x) ** 2 + sp.cos(x) ** 2, sp.Integer(1)),
        (a * sp.sin(x) ** 2 + a * sp.cos(x) ** 2 + b * (c**2 * sp.sin(y) ** 2 + c**2 * sp.cos(y) ** 2), a + b * c**2),
        (a * sp.sin(x) ** 2 + a * sp.cos(x) ** 2 + sp.sin(x) ** 2, a + sp.sin(x) ** 2),
    ],
)
def test_pythagorean_rewrite_removes_matched_pairs(expr, want):
    assert sp.simplify(pythagorean(expr) - want) == 0
    assert pythagorean(expr).count_ops() <= want.count_ops() + 2


@pytest.mark.parametrize(
    "expr",
    [
        sp.sin(x) ** 2 + sp.cos(y) ** 2,
        2 * sp.sin(x) ** 2 + sp.cos(x) ** 2,
        a * sp.sin(x) ** 2 + b * sp.cos(x) ** 2,
        sp.sin(x) + sp.cos(x),
    ],
)
def test_pythagorean_rewrite_leaves_unmatched_sums_alone(expr):
    assert pythagorean(expr) == expr


def test_pythagorean_rewrite_does_not_expand_large_powers():
    big = (sum(sp.symbols("s0:12")) + sp.sin(x)) ** 12 + sp.cos(x) ** 2
    assert pythagorean(big) == big  # returns at once: no multinomial expansion


@pytest.mark.parametrize(
    "name,variant", [("appell-hamel", "nonlinear"), ("appell-hamel", "linear"), ("sliding-particle", "nonminimal")]
)
def test_kernel_terms_are_the_derivations_matrices(name, variant):
    d = built(get_system(name)).derivation(variant)
    kt = kernel_terms(d)
    rng = np.random.default_rng(3)
    syms = list(d.model.q) + list(d.model.u) + list(d.model.params)
    for _ in range(5):
        sub = dict(zip(syms, rng.uniform(0.3, 2.0, len(syms)), strict=True))
        for mine, theirs in [(kt.Q, d.Q), (kt.P, d.P), (kt.J[:, : d.p], d.J1), (kt.b, d.b)]:
            diff = (mine - theirs).xreplace(sub).evalf()
            assert max((abs(v) for v in diff), default=0) < 1e-12


def test_appell_hamel_mass_matrix_has_no_needless_trigonometry():
    kt = kernel_terms(built(get_system("appell-hamel")).derivation("nonlinear"))
    md = kt.derivation.model
    params = {str(s): s for s in md.params}
    assert sp.expand(kt.Q[0, 0] - (params["I"] + params["M"] * params["rho"] ** 2)) == 0


def test_hot_path_is_one_function_after_source_inlining():
    src = generate_source(built(get_system("appell-hamel")).derivation("nonlinear"))
    stages = src[src.index("def _stages(") : src.index("def _record(")]
    for call in ("rhs_ws(", "terms(", "lu_solve_flat(", "_reduced_solve("):
        assert call not in stages, call
    assert "math.sin(x" not in stages and "math.sin(_" in stages  # terms, renamed apart
    rhs_ws = _function(src, "rhs_ws")
    assert "terms(" not in rhs_ws and "lu_solve_flat(" not in rhs_ws


def _function(src: str, name: str) -> str:
    """The source of the top-level function ``name`` (up to the next top-level statement)."""
    start = src.index(f"def {name}(")
    end = re.search(r"\n(?=[^\s#])", src[start:])
    return src[start : start + end.start()] if end else src[start:]


_MODULE = """
def f(a, b):
    c = a + b
    for i in range(2):
        c += i
    return c * 2

def g(x):
    c = 100
    i = 7
    y = f(x + 1, i)  # INLINE
    return y + c + i

def h(v):
    f(v, v)  # INLINE
    return v
"""


def test_inline_marked_binds_arguments_and_renames_locals_apart():
    out = inline_marked(_MODULE)
    assert "f(x + 1, i)" not in out and "f(v, v)" not in out
    ns_before, ns_after = {}, {}
    exec(_MODULE, ns_before)
    exec(out, ns_after)
    for v in (0, 3, -2.5):
        assert ns_after["g"](v) == ns_before["g"](v)
        assert ns_after["h"](v) == ns_before["h"](v)


def test_inline_marked_refuses_early_returns_and_leaves_unmarked_calls():
    with pytest.raises(RuntimeError, match="return"):
        inline_marked(
            "def f(a):\n    if a:\n        return 1\n    return 2\n\ndef g(x):\n    y = f(x)  # INLINE\n    return y\n"
        )
    plain = "def f(a):\n    return a\n\n# a comment\ndef g(x):\n    return f(x)\n"
    assert inline_marked(plain) == plain


def test_projection_helpers_compile_once_per_run(tmp_path):
    """Literal arguments (True, 0, 1) make numba compile one copy per value; the cold
    projection path passes runtime values so each helper has a single signature.  (In a
    fresh cache: helpers loaded with their caller from the disk cache list no signature.)"""
    import os
    import subprocess
    import sys

    code = (
        "from nmkane_core.run.simulate import simulate, kernel_for\n"
        "from nmkane_core import get_system\n"
        "r = simulate({'system': 'sliding-particle', 't_final': 0.1, 'projection': 'yoon'})\n"
        "m = kernel_for(get_system('sliding-particle'), 'nonminimal')\n"
        "print(r.summary['status'], len(m._weighted_correction.signatures), len(m.lu_solve_flat.signatures))\n"
    )
    env = {
        **os.environ,
        "NMKANE_CACHE_DIR": str(tmp_path),
        "NUMBA_CACHE_DIR": str(tmp_path),
        "NMKANE_PRECOMPILE": "0",
        "NMKANE_INTERPRET": "0",  # compiled, as this is about the compiled helpers
    }
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["ok", "1", "1"]


def test_unprojected_loop_is_compiled_without_the_projection():
    mod = kernel_for(get_system("sliding-particle"), "nonminimal")
    simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 0.2})
    proj = FixedArgs._fields.index("proj")
    sigs = [s for s in mod.integrate_fixed.signatures if str(s[proj]) == "none"]
    assert sigs, mod.integrate_fixed.signatures


def test_background_precompile_signature_is_the_one_runs_use():
    """The child process started for a new kernel compiles exactly the loop signature that
    unprojected fixed-step runs call, so the first run loads it instead of compiling."""
    from nmkane_core.kernel.precompile import fixed_loop_signature

    for name, variant in [("appell-hamel", "nonlinear"), ("sliding-particle", "nonminimal")]:
        system = get_system(name)
        simulate({"system": name, system.option: variant, "dt": 0.01, "t_final": 0.1})
        mod = kernel_for(system, variant)
        assert fixed_loop_signature() in mod.integrate_fixed.signatures


def test_loop_argument_records_are_the_loops_parameters_and_the_signatures_runs_use():
    """FixedArgs/AdaptiveArgs are the compiled loops' parameters in order (the generator writes
    them into the loops' ``def``; the drivers and the precompile signature come from them), and
    their numba types are those of real runs."""
    import ast
    import inspect

    mod = kernel_for(get_system("sliding-particle"), "nonminimal")
    tree = ast.parse(inspect.getsource(mod))
    params = {n.name: [a.arg for a in n.args.args] for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert params["integrate_fixed"] == list(FixedArgs._fields)
    assert params["integrate_adaptive"] == list(AdaptiveArgs._fields)
    for settings, loop, args in [
        ({}, mod.integrate_fixed, FixedArgs),
        ({"integrator": "kutta-merson-adaptive"}, mod.integrate_adaptive, AdaptiveArgs),
    ]:
        for projection in ("none", "yoon"):
            simulate({"system": "sliding-particle", "dt": 0.01, "t_final": 0.2, "projection": projection, **settings})
            assert loop_signature(args, projected=projection != "none") in loop.signatures, loop.signatures


def test_scipy_runs_compile_before_their_clock_starts(tmp_path):
    """In a fresh cache the first scipy run compiled the right-hand side inside its timed
    region (a fuzz run with time_limit=2 s took over 4 s); prepare() now does it first."""
    import os
    import subprocess
    import sys

    code = (
        "from nmkane_core import simulate\n"
        "r = simulate({'system': 'sliding-particle', 'formulation': 'minimal', 'integrator': 'radau',"
        " 't_final': 0.5})\n"
        "print(r.status, r.summary['wall_time_s'], r.summary['kernel_load_s'])\n"
    )
    env = {**os.environ, "NMKANE_CACHE_DIR": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    status, wall, load = out.stdout.split()
    assert status == "ok"
    assert float(wall) < float(load)  # compiling (seconds) happened in kernel_load_s


def test_the_callees_compiled_beside_a_new_loop_are_those_the_loops_call():
    """While a child compiles a new kernel's loop, the waiting process compiles the loop's
    callees for the signatures ``callee_signatures`` lists (kernel.precompile.wait); a listed
    type that is not the one the loops call (a literal int, an array layout) would compile
    something no loop uses and leave the child to compile it again."""
    import numba

    from nmkane_core.kernel.interface import LOOPS, callee_signatures

    mod = kernel_for(get_system("knife-edge"), None)
    for loop, projected in (("integrate_fixed", False), ("integrate_fixed", True), ("integrate_adaptive", True)):
        fresh = numba.njit(cache=False, nogil=True, error_model="numpy")(getattr(mod, loop).py_func)
        fresh.compile(loop_signature(LOOPS[loop], projected))  # its callees: loaded or compiled, typed
        for name, signature in callee_signatures(mod, projected).items():
            called = list(getattr(mod, name).overloads)
            assert tuple(signature) in called, (loop, name, called)


def test_a_kernels_imports_load_no_pydantic_registry_or_sympy():
    """Every generated kernel imports ``nmkane_core.kernel.constants``; with the package's names
    bound on first use (nmkane_core/__init__.py) that costs 0.01 s, not the 0.84 s of pydantic,
    the registry and the run machinery — in the background compiling child too."""
    import subprocess
    import sys

    code = (
        "import sys, nmkane_core.kernel.constants, nmkane_core.kernel.precompile\n"
        "heavy = ('pydantic', 'sympy', 'nmkane_core.run', 'nmkane_core.schema', 'nmkane_core.declare')\n"
        "print(sorted(m for m in sys.modules if m.startswith(heavy)))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
    code = "import nmkane_core\nprint(nmkane_core.simulate.__module__, 'simulate' in vars(nmkane_core))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["nmkane_core.run.simulate", "True"]
