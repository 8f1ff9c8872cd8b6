"""Derived matrices equal the paper's printed ones (Appell–Hamel (65)–(76), (99)–(100);
sliding particle (116)–(117), (121)–(122), (125)–(126), (137)).

Compared numerically at random states (not only consistent ones: the printed formulas are
identities in q and u), with the derivation's symbolic matrices and with both numeric
kernels (numpy reference and compiled)."""

import numpy as np
import pytest
import sympy as sp

from nmkane_core import get_system
from nmkane_core.kernel.built import built
from nmkane_core.run.simulate import kernel_for
from nmkane_core.symbolic.reference import ReferenceKernel

RNG = np.random.default_rng(2005)
AH_PARAMS = dict(a=1.0, b=0.5, rho=5.0, m=1.0, M=5.0, I=2.5, g=9.81, z0=30.0)


def _ah_subs(th, ph, x, y, z, u, prm):
    d = built(get_system("appell-hamel")).derivation("nonlinear")
    md = d.model
    sub = dict(zip(md.q, (th, ph, x, y, z), strict=True))
    sub.update(zip(md.u, u, strict=True))
    sub.update({s: prm[str(s)] for s in md.params})
    return sub


def _paper_ah(th, u, prm):
    """(65)–(76) as printed, with n1..n6 of (67)–(70), (73)–(74)."""
    a, b, rho = prm["a"], prm["b"], prm["rho"]
    u1, u2, u3, u4, _u5 = u
    s, c = np.sin(th), np.cos(th)
    n1 = rho**2 * u1 + rho * u3 * s - rho * u4 * c
    n2 = -(a**2) * u2
    n3 = u3 + rho * u1 * s
    n4 = u4 - rho * u1 * c
    n5 = n3 * c + n4 * s
    n6 = u3 * c + u4 * s
    J1 = np.array([[n1, n2], [rho, 0], [0, b]])
    J2 = np.array([[n3, n4, 0], [s, -c, 0], [0, 0, 1]])
    A = np.array([[-rho * n4 - n1 * c, -n2 * c], [rho * n3 - n1 * s, -n2 * s], [0, -n5 * b]]) / n5
    B = n6 / n5 * np.array([-u1 * (n4 + rho * u1 * c), u1 * (n3 - rho * u1 * s), 0])
    A1 = np.array(
        [
            [(rho * n4 + n1 * c) / n5, n2 * c / n5, 1, 0, 0],
            [(-rho * n3 + n1 * s) / n5, n2 * s / n5, 0, 1, 0],
            [0, b, 0, 0, 1],
        ]
    )
    A2 = np.array(
        [[1, 0, (-rho * n4 - n1 * c) / n5, (rho * n3 - n1 * s) / n5, 0], [0, 1, -n2 * c / n5, -n2 * s / n5, -b]]
    )
    M, m, I, g = prm["M"], prm["m"], prm["I"], prm["g"]
    Q = np.array(
        [
            [M * rho**2 + I, 0, M * rho * s, -M * rho * c, 0],
            [0, I, 0, 0, 0],
            [M * rho * s, 0, M + m, 0, 0],
            [-M * rho * c, 0, 0, M + m, 0],
            [0, 0, 0, 0, m],
        ]
    )
    P = np.array([0, 0, -M * rho * u1**2 * c, -M * rho * u1**2 * s, -m * g])
    return dict(J1=J1, J2=J2, A=A, B=B, A1=A1, A2=A2, Q=Q, P=P)


def _random_ah_state():
    th, ph = RNG.uniform(-np.pi, np.pi, 2)
    x, y = RNG.uniform(-10, 10, 2)
    z = RNG.uniform(-50, 50)
    u = RNG.uniform(-3, 3, 5)
    prm = dict(AH_PARAMS)
    prm.update(
        a=RNG.uniform(0.3, 2),
        b=RNG.uniform(0.1, 1),
        rho=RNG.uniform(1, 8),
        M=RNG.uniform(1, 10),
        m=RNG.uniform(0.5, 3),
        I=RNG.uniform(0.5, 5),
    )
    return th, ph, x, y, z, u, prm


@pytest.mark.parametrize("trial", range(8))
def test_appell_hamel_symbolic_matrices_match_paper_65_to_76_and_99_100(trial):
    d = built(get_system("appell-hamel")).derivation("nonlinear")
    th, ph, x, y, z, u, prm = _random_ah_state()
    sub = _ah_subs(th, ph, x, y, z, u, prm)
    ev = lambda M: np.array(M.subs(sub).evalf(), dtype=float)  # noqa: E731
    paper = _paper_ah(th, u, prm)
    # (60) is (57) differentiated and divided by 2: our first rows are twice the paper's
    scale = np.diag([0.5, 1.0, 1.0])
    np.testing.assert_allclose(scale @ ev(d.J1), paper["J1"], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(scale @ ev(d.J2), paper["J2"], rtol=1e-12, atol=1e-12)
    for name in ("A", "B", "A1", "A2", "Q", "P"):
        got = ev(d.matrix(name)).ravel()
        np.testing.assert_allclose(got, paper[name].ravel(), rtol=1e-10, atol=1e-10, err_msg=name)


@pytest.mark.parametrize("trial", range(5))
def test_appell_hamel_numeric_kernels_match_paper_matrices(trial):
    system = get_system("appell-hamel")
    th, ph, x, y, z, u, prm = _random_ah_state()
    ref = ReferenceKernel(built(system).derivation("nonlinear"))
    xs = np.array([th, ph, x, y, z, *u])
    p = np.array([prm[k] for k in system.param_names])
    mats = ref.matrices(0.0, xs, p)
    paper = _paper_ah(th, u, prm)
    for name in ("A", "A1", "A2", "Q", "P"):
        np.testing.assert_allclose(mats[name], paper[name], rtol=1e-9, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(mats["B_hat"], paper["B"], rtol=1e-9, atol=1e-9)
    T = np.vstack([paper["A1"], paper["A2"] @ paper["Q"]])
    np.testing.assert_allclose(mats["T"], T, rtol=1e-9, atol=1e-9)
    udot = np.linalg.solve(T, np.concatenate([paper["B"], paper["A2"] @ paper["P"]]))
    mod = kernel_for(system, "nonlinear")
    xdot, _rc_j2, _rc_t = mod.rhs(0.0, xs, p, np.zeros((2, 2)), np.zeros((1, 1)), np.zeros((1, 1)))
    np.testing.assert_allclose(xdot[5:], udot, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(xdot[:5], u, rtol=0, atol=0)


def test_appell_hamel_linear_model_has_printed_structure():
    """(101)–(102): J1, J2 of the linear model and A = −J2⁻¹J1 with J2 = −I on (u3, u4)."""
    d = built(get_system("appell-hamel")).derivation("linear")
    th = sp.Symbol("theta", real=True)
    a, b, rho = sp.symbols("a b rho", real=True)
    J1 = sp.Matrix([[-rho * sp.sin(th), a * sp.cos(th)], [rho * sp.cos(th), a * sp.sin(th)], [0, b]])
    J2 = sp.Matrix([[-1, 0, 0], [0, -1, 0], [0, 0, 1]])
    assert sp.simplify(d.J1 - J1) == sp.zeros(3, 2)
    assert d.J2 == J2
    assert sp.simplify(
        d.A - sp.Matrix([[-rho * sp.sin(th), a * sp.cos(th)], [rho * sp.cos(th), a * sp.sin(th)], [0, -b]])
    ) == sp.zeros(3, 2)


def test_sliding_particle_matrices_match_paper_116_117():
    d = built(get_system("sliding-particle")).derivation("nonminimal")
    x, l0, u1 = sp.symbols("x l0 u1", real=True)
    assert sp.simplify(d.A1 - sp.Matrix([[2 * x / l0, 1]])) == sp.zeros(1, 2)
    assert sp.simplify(d.A2 - sp.Matrix([[1, -2 * x / l0]])) == sp.zeros(1, 2)
    assert sp.simplify(d.B - sp.Matrix([-2 * u1**2 / l0])) == sp.zeros(1, 1)


def _particle_paper_udot(x, y, u1, u2, g, G1, G2):
    """(125)–(126) with l0 = 1 (G1 = G2 = 0 gives (121)–(122))."""
    den = 1 + 4 * x**2
    ud1 = -2 * x * (g + 2 * u1**2) / den + 2 * x * (u2 + 2 * x * u1) / den * G1 - 2 * x * (1 - y - x**2) / den * G2
    ud2 = (4 * g * x**2 - 2 * u1**2) / den + (u2 + 2 * x * u1) / den * G1 - (1 - y - x**2) / den * G2
    return np.array([ud1, ud2])


@pytest.mark.parametrize("gains", [(0.0, 0.0), (-20.0, -100.0), (3.0, -7.5)])
def test_sliding_particle_rhs_matches_paper_121_122_125_126(gains):
    system = get_system("sliding-particle")
    mod = kernel_for(system, "nonminimal")
    ref = ReferenceKernel(built(system).derivation("nonminimal"))
    g = 9.81
    p = np.array([1.0, 1.0, g])
    G1, G2 = np.array([[gains[0]]]), np.array([[gains[1]]])
    for _ in range(20):
        x, y, u1, u2 = RNG.uniform(-2, 2, 4)
        xs = np.array([x, y, u1, u2])
        want = _particle_paper_udot(x, y, u1, u2, g, *gains)
        xdot, _, _ = mod.rhs(0.0, xs, p, np.zeros((0, 0)), G1, G2)
        np.testing.assert_allclose(xdot[2:], want, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ref.rhs(0.0, xs, p, np.zeros((0, 0)), G1, G2)[2:], want, rtol=1e-12, atol=1e-12)


def test_sliding_particle_minimal_equation_matches_paper_137():
    system = get_system("sliding-particle")
    mod = kernel_for(system, "minimal")
    g = 9.81
    for _ in range(20):
        x, u1 = RNG.uniform(-2, 2, 2)
        xdot, _, _ = mod.rhs(
            0.0, np.array([x, u1]), np.array([1.0, 1.0, g]), np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0))
        )
        # (137): 2gx + u̇1 + 2x(2u1² + 2x u̇1) = 0
        assert abs(2 * g * x + xdot[1] + 2 * x * (2 * u1**2 + 2 * x * xdot[1])) < 1e-11


def test_latex_of_derived_matrices_is_printable():
    d = built(get_system("sliding-particle")).derivation("nonminimal")
    tex = d.latex("A1")
    assert tex.startswith("A_1 = ") and "\\frac{2 x}{l_{0}}" in tex
