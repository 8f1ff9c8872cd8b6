"""Code generation: the exact rewrites applied before printing, the kernel description, and
what loading a kernel imports."""

import json

import numpy as np
import pytest
import sympy as sp

from nmkane_core import get_system
from nmkane_core.kernel.built import built
from nmkane_core.kernel.codegen import generate_source
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


def test_a_kernel_description_is_the_same_text_for_the_same_model():
    """The description is keyed by its text (kernel.loader.source_key): deriving a model twice
    must give the same text, or every process would build the model's library again."""
    d = built(get_system("appell-hamel")).derivation("nonlinear")
    one, two = generate_source(d), generate_source(d)
    assert one == two
    described = json.loads(one)
    assert described["ints"]["N"] == 5 and "nmk_" + described["tag"] + "_terms" in described["c_source"]


def test_a_kernels_imports_load_no_pydantic_registry_or_sympy():
    """Loading a kernel imports ``nmkane_core.kernel.cmodel`` and the core's bindings; with the
    package's names bound on first use (nmkane_core/__init__.py) that costs little, not the 0.84 s
    of pydantic, the registry and the run machinery."""
    import subprocess
    import sys

    code = (
        "import sys, nmkane_core.kernel.constants, nmkane_core.kernel.cmodel, nmkane_core.kernel.core\n"
        "heavy = ('pydantic', 'sympy', 'nmkane_core.run', 'nmkane_core.schema', 'nmkane_core.declare')\n"
        "print(sorted(m for m in sys.modules if m.startswith(heavy)))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
    code = "import nmkane_core\nprint(nmkane_core.simulate.__module__, 'simulate' in vars(nmkane_core))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["nmkane_core.run.simulate", "True"]
