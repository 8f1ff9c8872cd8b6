"""The rank-robust constraint solve of the numpy reference (docs/closed-loops.md): Gauss's
principle in the mass metric through a Cholesky factor of Q and a Householder QR with
column pivoting of L⁻¹Jᵀ.  Checked against LAPACK and the KKT system on random data, against
the paper's T u̇ = V̂ path on the paper's own systems (where J2 is invertible the two are the
same equations), and on a redundant and a singular case."""

import numpy as np
import pytest
import scipy.linalg as sla

from nmkane_core import get_system
from nmkane_core.errors import SingularMatrix
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import default_state
from nmkane_core.symbolic.reference import (
    ReferenceKernel,
    cholesky_lower,
    partition_by_pivoting,
    qr_column_pivoting,
    robust_solve,
)


def _spd(rng, n):
    M = rng.standard_normal((n, n))
    return M @ M.T + n * np.eye(n)


def test_qr_with_column_pivoting_has_lapacks_pivots_and_numerical_rank():
    rng = np.random.default_rng(1)
    for n, m, deficient in [(9, 6, 1), (8, 8, 0), (12, 5, 2), (5, 7, 0)]:
        A = rng.standard_normal((n, m))
        for k in range(deficient):  # exact linear dependencies
            A[:, -1 - k] = A[:, 0] - 2 * A[:, 1 + k]
        H, _, piv, r = qr_column_pivoting(A, 1e-10)
        _, R, lapack_piv = sla.qr(A, mode="economic", pivoting=True)
        assert r == np.linalg.matrix_rank(A) == min(n, m) - deficient
        np.testing.assert_array_equal(piv[:r], lapack_piv[:r])
        np.testing.assert_allclose(np.abs(np.diag(H)[:r]), np.abs(np.diag(R))[:r], rtol=1e-12)


def test_cholesky_loop_matches_lapack_and_refuses_an_indefinite_matrix():
    rng = np.random.default_rng(2)
    Q = _spd(rng, 7)
    np.testing.assert_allclose(cholesky_lower(Q), np.linalg.cholesky(Q), rtol=1e-13, atol=1e-13)
    Q[0, 0] = -1.0
    assert cholesky_lower(Q) is None
    with pytest.raises(SingularMatrix):
        robust_solve(Q, np.ones(7), np.ones((1, 7)), np.zeros(1))


def test_robust_solve_is_the_kkt_solution_with_its_multipliers():
    rng = np.random.default_rng(3)
    for n, m in [(7, 3), (5, 4), (9, 1)]:
        Q, P = _spd(rng, n), rng.standard_normal(n)
        J, c = rng.standard_normal((m, n)), rng.standard_normal(m)
        kkt = np.linalg.solve(np.block([[Q, -J.T], [J, np.zeros((m, m))]]), np.concatenate([P, c]))
        sol = robust_solve(Q, P, J, c)
        np.testing.assert_allclose(sol.udot, kkt[:n], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(sol.lam, kkt[n:], rtol=1e-11, atol=1e-11)  # Q u̇ = P + Jᵀλ
        assert sol.rank == m and not sol.dependent and sol.residual < 1e-13


def test_redundant_equations_give_the_same_motion_and_are_named_as_dependent():
    rng = np.random.default_rng(4)
    Q, P = _spd(rng, 6), rng.standard_normal(6)
    J, c = rng.standard_normal((3, 6)), rng.standard_normal(3)
    want = robust_solve(Q, P, J, c).udot
    J2 = np.vstack([J, 2 * J[0] - J[2]])  # a fourth, dependent equation
    c2 = np.append(c, 2 * c[0] - c[2])
    sol = robust_solve(Q, P, J2, c2)
    np.testing.assert_allclose(sol.udot, want, rtol=1e-12, atol=1e-12)
    assert sol.rank == 3 and len(sol.dependent) == 1 and sol.residual < 1e-13
    np.testing.assert_allclose(J2.T @ sol.lam, Q @ sol.udot - P, atol=1e-11)  # F_c = Jᵀλ still
    # capped at the model's rank: a nearly dependent fourth equation is dropped all the same
    J3 = J2.copy()
    J3[3] += 1e-6 * rng.standard_normal(6)
    assert robust_solve(Q, P, J3, c2).rank == 4
    capped = robust_solve(Q, P, J3, c2, max_rank=3)
    assert capped.rank == 3
    np.testing.assert_allclose(capped.udot, want, atol=1e-5)
    # an inconsistent dependent equation is measured (a run then ends singular)
    c2[3] += 1e-2
    assert robust_solve(Q, P, J2, c2).residual > 1e-4


def test_wehage_haug_partition_picks_an_invertible_j2():
    rng = np.random.default_rng(5)
    J = rng.standard_normal((3, 6))
    J[:, 4] = 0.0  # a speed no constraint involves can never be dependent
    dep, rows, rank = partition_by_pivoting(J)
    assert rank == 3 and sorted(rows) == [0, 1, 2] and 4 not in dep
    assert abs(np.linalg.det(J[:, dep])) > 1e-6


PAPER = [("appell-hamel", "nonlinear"), ("appell-hamel", "linear"), ("sliding-particle", "nonminimal")]


def _consistent_states(ref, md, rng, count):
    """Random states moved onto the constraints (the reference's mass-metric projection)."""
    out = []
    while len(out) < count:
        x = rng.uniform(-2, 2, 2 * md.n) + np.r_[np.zeros(md.n), np.full(md.n, 0.5)]
        p = np.array([rng.uniform(0.5, 2) for _ in md.params])
        try:
            x = ref.project(0.3, x, p, iterations=30)
        except (SingularMatrix, np.linalg.LinAlgError):
            continue
        if np.all(np.isfinite(x)) and max(np.abs(ref.violation(0.3, x, p)).max(initial=0.0), 0) < 1e-10:
            out.append((x, p))
    return out


@pytest.mark.parametrize("name,variant", PAPER)
def test_robust_solve_matches_the_papers_T_udot_V_path_to_1e12(name, variant):
    """Where J2 is invertible the paper's (44)/(110) and Gauss's principle are the same
    equations: at the paper's initial state and at random consistent states, with random
    Baumgarte gains, the two solves agree to round-off."""
    system = get_system(name)
    ref = ReferenceKernel(built(system).derivation(variant))
    md = built(system).model(variant)
    rng = np.random.default_rng(11)
    x0 = np.array([default_state(system)[str(s)] for s in md.q + md.u])
    p0 = np.array([system.parameter(str(s)).default for s in md.params])
    states = [(x0, p0), *_consistent_states(ref, md, rng, 20)]
    for x, p in states:
        G = rng.uniform(-5, 0, (len(md.nonholonomic),) * 2)
        G1 = rng.uniform(-30, 0, (len(md.holonomic),) * 2)
        G2 = rng.uniform(-100, 0, (len(md.holonomic),) * 2)
        want = ref.rhs(0.3, x, p, G, G1, G2)
        got = ref.rhs(0.3, x, p, G, G1, G2, solve="robust")
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())
        auto = ref.rhs(0.3, x, p, G, G1, G2, solve="auto")
        np.testing.assert_array_equal(auto, want)  # the paper's path, untouched, where J2 is fine
    assert ref.switches == []


def test_auto_repartitions_where_the_declared_j2_is_singular_and_says_so():
    """The pendulum (IFToMM A01) with u_D = ẋ: J2 = 2x vanishes where the bar hangs down.
    There the paper's path stops; ``solve="auto"`` picks u_D = ẏ by pivoting on J (Wehage &
    Haug) and gives the exact acceleration; where the bar is horizontal it goes back to u_D = ẋ,
    and records that switch (the first choice is not one)."""
    from nmkane_core.symbolic.derivation import derive
    from nmkane_core.systems import iftomm_a01

    ref = ReferenceKernel(derive(iftomm_a01.model("cartesian", "u1")))
    v, g, p = 2.0, 9.81, np.array([1.0, 1.0, 9.81])
    bottom = np.array([0.0, -1.0, v, 0.0])
    with pytest.raises(SingularMatrix):
        ref.rhs(0.0, bottom, p)
    np.testing.assert_allclose(ref.rhs(0.0, bottom, p, solve="auto")[2:], [0.0, v * v], atol=1e-12)  # centripetal only
    assert ref.switches == []
    horizontal = np.array([1.0, 1e-15, 0.0, v])
    np.testing.assert_allclose(ref.rhs(0.5, horizontal, p, solve="auto")[2:], [-v * v, -g], atol=1e-12)
    assert ref.switches == [{"t": 0.5, "solve": "paper", "u_dependent": ["u1"]}]
