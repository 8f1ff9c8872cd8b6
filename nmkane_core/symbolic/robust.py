"""The rank-robust constraint solve, in numpy: the specification of the compiled kernel's.

Gauss's principle in the mass metric — u̇ minimizes (u̇ − a)ᵀQ(u̇ − a) subject to J u̇ = c,
a = Q⁻¹P, c = −(B1 u + B2) + s — through a Cholesky factor of Q and a Householder QR with
column pivoting of the equilibrated L⁻¹Jᵀ (:func:`robust_solve`); Wehage & Haug's partition
by complete pivoting (:func:`partition_by_pivoting`) and a scale-free estimate of a
partition's J2 (:func:`partition_rcond`).  Written with explicit loops (no LAPACK call in
the algorithm) so that the compiled, allocation-free version is a transcription; the
design, the thresholds and the evidence are in ``docs/closed-loops.md``.
:class:`~nmkane_core.symbolic.reference.ReferenceKernel` uses it for ``solve="robust"`` and
``solve="auto"`` and for its projection.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import SingularMatrix

#: relative threshold of the rank decisions in the robust solve: a constraint gradient
#: (a column of L⁻¹Jᵀ) shorter than this times the longest is vanishing there, and a pivot
#: of the QR of the equilibrated columns below it marks an equation dependent on the
#: previous ones (see docs/closed-loops.md for the choice)
RANK_TOL = 1e-10
#: rank threshold of the declaration check (redundant equations at the default state)
DECLARATION_RANK_TOL = 1e-8
#: the acceleration constraints J u̇ = c are called inconsistent (the motion cannot stay on
#: the constraints: a run ends ``singular``) when the equations dropped as dependent miss
#: by more than this, relative to the size of c
CONSISTENCY_TOL = 1e-6
#: below this estimate of J2's condition (pivot ratio) ``solve="auto"`` leaves the paper's
#: path: it re-picks the partition, or uses the robust solve
RCOND_ROBUST = 1e-6
#: a row of J shorter than this share of the longest (a constraint whose gradient vanishes at a
#: singular position) gets its Baumgarte term scaled by (share / BAUMGARTE_FADE)²
#: (:func:`fade_baumgarte`): Γ1ψ̇ + Γ2ψ asks accelerations of order Γψ/|J_i| there, kicks that
#: a four-bar chain's passages through its flat position turned into a velocity error of 1.4e-6
#: after 10 s at Δt = 5e-4 (4e-9 with the fade; docs/closed-loops.md §7.3)
BAUMGARTE_FADE = 1e-3


def fade_baumgarte(J: np.ndarray, s: np.ndarray) -> np.ndarray:
    """The Baumgarte vector s with the terms of vanishing rows of J faded out
    (:data:`BAUMGARTE_FADE`; the rows' ∞-norms against the longest).  Near a singular position
    the projection, or the row's return, takes care of the drift."""
    s = np.array(s, float)
    if not len(s):
        return s
    norms = np.abs(J).max(axis=1)
    longest = norms.max()
    if longest > 0.0:
        share = norms / longest
        low = share < BAUMGARTE_FADE
        s[low] *= (share[low] / BAUMGARTE_FADE) ** 2
    return s


# --------------------------------------------------------------------------- rank-robust solve
class ConstraintsInconsistent(SingularMatrix):
    """J u̇ = c has no solution: c is not in the range of J (at a singular or redundant
    position the dependent equations disagree), so the motion cannot stay on the constraints."""

    def __init__(self, t: float, rank: int, m: int, dropped: list, residual: float):
        self.rank, self.m, self.dropped, self.residual = rank, m, dropped, residual
        ArithmeticError.__init__(
            self,
            f"the acceleration constraints are inconsistent at t = {t:.6g} s: rank {rank} of {m}, the "
            f"dependent equations {dropped} miss by {residual:.3g} (relative); the motion cannot "
            "continue on the constraints here",
        )
        self.matrix, self.rcond, self.t = "J", 0.0, t


def cholesky_lower(Q: np.ndarray) -> np.ndarray | None:
    """Q = L Lᵀ by the column (Cholesky–Banachiewicz) loop; None when Q is not positive definite."""
    n = Q.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = Q[j, j] - L[j, :j] @ L[j, :j]
        if not d > 0.0:
            return None
        L[j, j] = np.sqrt(d)
        L[j + 1 :, j] = (Q[j + 1 :, j] - L[j + 1 :, :j] @ L[j, :j]) / L[j, j]
    return L


def forward_solve(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """L X = B for lower-triangular L (B a vector or a matrix, by rows)."""
    X = np.array(B, float, copy=True)
    for i in range(L.shape[0]):
        X[i] = (X[i] - L[i, :i] @ X[:i]) / L[i, i]
    return X


def backward_solve_transposed(L: np.ndarray, B: np.ndarray) -> np.ndarray:
    """Lᵀ X = B for lower-triangular L."""
    X = np.array(B, float, copy=True)
    n = L.shape[0]
    for i in range(n - 1, -1, -1):
        X[i] = (X[i] - L[i + 1 :, i] @ X[i + 1 :]) / L[i, i]
    return X


def qr_column_pivoting(A: np.ndarray, tol: float, max_rank: int | None = None):
    """Householder QR with column pivoting, A Π = Z R, stopped at the numerical rank.

    At step k the remaining column of largest norm (recomputed exactly; the first one on a
    tie) becomes column k; the step stops when that norm is at most ``tol`` times the first
    pivot's, or after ``max_rank`` steps.  Returns (H, beta, piv, rank): H holds R on and
    above its diagonal (rows
    ``< rank``) and the Householder vectors below it (LAPACK's layout, v_k[0] = 1 implied by
    storing v_k scaled), beta the reflector coefficients (H_k = I − beta_k v_k v_kᵀ), piv
    the column order (the first ``rank`` are the independent ones)."""
    H = np.array(A, float, copy=True)
    n, m = H.shape
    piv = np.arange(m)
    beta = np.zeros(m)
    first = 0.0
    rank = 0
    for k in range(min(n, m) if max_rank is None else min(n, m, max_rank)):
        norms = np.einsum("ij,ij->j", H[k:, k:], H[k:, k:])
        j = k + int(np.argmax(norms))
        nk = float(np.sqrt(norms[j - k]))
        if k == 0:
            first = nk
        if nk <= tol * first or nk == 0.0:
            break
        if j != k:
            H[:, [k, j]] = H[:, [j, k]]
            piv[[k, j]] = piv[[j, k]]
        x0 = H[k, k]
        alpha = -nk if x0 >= 0.0 else nk
        v0 = x0 - alpha  # v = x − alpha e1, scaled so that v[0] = 1
        H[k + 1 :, k] /= v0
        beta[k] = -v0 / alpha  # = 2 / (vᵀv) for the scaled v
        H[k, k] = alpha
        if k + 1 < m:  # apply H_k to the remaining columns
            w = H[k, k + 1 :] + H[k + 1 :, k] @ H[k + 1 :, k + 1 :]
            H[k, k + 1 :] -= beta[k] * w
            H[k + 1 :, k + 1 :] -= beta[k] * np.outer(H[k + 1 :, k], w)
        rank = k + 1
    return H, beta, piv, rank


def _apply_Z(H: np.ndarray, beta: np.ndarray, rank: int, y: np.ndarray) -> np.ndarray:
    """Z_r y = H_0 H_1 … H_{r−1} [y; 0] (the reflectors applied in reverse order)."""
    z = np.zeros(H.shape[0])
    z[:rank] = y
    for k in range(rank - 1, -1, -1):
        d = z[k] + H[k + 1 :, k] @ z[k + 1 :]
        z[k] -= beta[k] * d
        z[k + 1 :] -= beta[k] * d * H[k + 1 :, k]
    return z


class RobustSolution:
    """What :func:`robust_solve` found: u̇, the multipliers λ (F_c = Jᵀλ, the basic
    solution: zero on the dependent equations), the rank of J, the equations kept
    (``independent``, in pivot order) and dropped (``dependent``: vanishing gradients
    first, then those the QR found dependent), the pivots |R_kk| (their smallest is the
    conditioning of the constraint normals in the mass metric) and the relative residual
    of the dropped equations."""

    __slots__ = ("dependent", "independent", "lam", "m", "pivots", "rank", "residual", "udot")

    def __init__(self, udot, lam, rank, independent, dependent, pivots, residual, m):
        self.udot, self.lam, self.rank = udot, lam, rank
        self.independent, self.dependent, self.pivots = independent, dependent, pivots
        self.residual, self.m = residual, m

    @property
    def rcond(self) -> float:
        """Smallest kept pivot (the equilibrated constraint normals' conditioning), 1 when m = 0."""
        return float(self.pivots.min()) if self.pivots.size else 1.0


def robust_solve(Q, P, J, c, tol: float = RANK_TOL, max_rank: int | None = None) -> RobustSolution:
    """Gauss's principle in the mass metric: u̇ = argmin (u̇ − a)ᵀQ(u̇ − a) s.t. J u̇ = c, a = Q⁻¹P.

    1. Q = L Lᵀ (Cholesky; Q not positive definite → :class:`SingularMatrix` "Q");
    2. â = L⁻¹P, K = L⁻¹Jᵀ (n×m): in w = Lᵀu̇ the problem is min |w − â|² s.t. Kᵀw = c;
    3. the columns of K (constraint normals in the mass metric) with norm ≤ tol·max are
       vanishing (dropped); the others are scaled to unit norm (row equilibration of J);
    4. Householder QR with column pivoting of the scaled K: K̃ Π = Z R, rank r where the
       pivot falls to ``tol`` — and at most ``max_rank``, the number of independent equations
       of the model (n − p): off the constraint manifold redundant equations are only
       nearly dependent, and near a singular position that "nearly" can exceed any
       threshold — the rank must then come from the model, not from the pivots;
    5. e = D(c − Kᵀâ) permuted; R11ᵀ y = e[:r]; the dropped equations' residual is
       e[r:] − R12ᵀ y (and e of the vanishing ones);
    6. w = â + Z_r y, u̇ = L⁻ᵀ w; λ from R11 λ̃ = y (zero on the dropped equations).

    Where J has full rank m this is the unique solution of J u̇ = c, Nᵀ(Q u̇ − P) = 0 (N a
    basis of J's null space) — the paper's (44)/(110) for any invertible J2."""
    Q = np.asarray(Q, float)
    P = np.asarray(P, float)
    J = np.asarray(J, float).reshape(-1, Q.shape[0])
    c = np.asarray(c, float)
    m = J.shape[0]
    L = cholesky_lower(Q)
    if L is None:
        raise SingularMatrix("Q", 0.0, float("nan"))
    a_hat = forward_solve(L, P)
    if m == 0:
        return RobustSolution(backward_solve_transposed(L, a_hat), np.zeros(0), 0, [], [], np.zeros(0), 0.0, 0)
    K = forward_solve(L, J.T)  # n×m
    norms = np.sqrt(np.einsum("ij,ij->j", K, K))
    big = norms.max(initial=0.0)
    keep = np.flatnonzero(norms > tol * big) if big > 0.0 else np.zeros(0, int)
    vanishing = [int(i) for i in np.flatnonzero(~np.isin(np.arange(m), keep))]
    e_all = c - K.T @ a_hat
    scale = max(np.abs(c).max(initial=0.0), np.abs(K.T @ a_hat).max(initial=0.0), 1e-300)
    Ks = K[:, keep] / norms[keep]
    es = e_all[keep] / norms[keep]
    H, beta, piv, r = qr_column_pivoting(Ks, tol, max_rank)
    ep = es[piv]
    R11 = np.triu(H[:r, :r])
    y = forward_solve(R11.T, ep[:r])
    res_dep = ep[r:] - H[:r, r:].T @ y  # residual of the dependent equations (scaled rows)
    residual = (
        max(
            float(np.abs(res_dep * norms[keep][piv[r:]]).max(initial=0.0)),
            float(np.abs(e_all[vanishing]).max(initial=0.0)),
        )
        / scale
    )
    w = a_hat + _apply_Z(H, beta, r, y)
    udot = backward_solve_transposed(L, w)
    lam_t = backward_solve_transposed(R11.T, y) if r else np.zeros(0)  # R11 λ̃ = y
    lam = np.zeros(m)
    lam[keep[piv[:r]]] = lam_t / norms[keep[piv[:r]]]
    independent = [int(i) for i in keep[piv[:r]]]
    dependent = vanishing + [int(i) for i in keep[piv[r:]]]
    return RobustSolution(udot, lam, r, independent, dependent, np.abs(np.diag(R11)), residual, m)


def partition_by_pivoting(J: np.ndarray, tol: float = RANK_TOL) -> tuple[list[int], list[int], int]:
    """Wehage & Haug's partition: Gaussian elimination with complete pivoting on J (rows
    equilibrated).  Returns (dependent columns — u_D, in pivot order —, independent rows,
    rank); the remaining columns are u_I, the remaining rows redundant there."""
    steps = pivot_steps(J, tol)
    return [c for c, _, _ in steps], [r for _, r, _ in steps], len(steps)


def pivot_steps(J: np.ndarray, tol: float = RANK_TOL) -> list[tuple[int, int, float]]:
    """The steps of :func:`partition_by_pivoting`, each (column made dependent, row it is solved
    from, |pivot| in the equilibrated elimination) — why the partition is what it is."""
    A = np.array(J, float, copy=True)
    m, n = A.shape
    rn = np.abs(A).max(axis=1, initial=0.0)
    big = rn.max(initial=0.0)
    rows = [i for i in range(m) if rn[i] > tol * big]
    A = A[rows] / rn[rows, None] if rows else np.zeros((0, n))
    row_id, col_id = list(rows), list(range(n))
    steps = []
    for _ in range(min(A.shape)):
        if A.size == 0:
            break
        i, j = np.unravel_index(int(np.argmax(np.abs(A))), A.shape)
        if abs(A[i, j]) <= tol:
            break
        steps.append((col_id[j], row_id[i], float(abs(A[i, j]))))
        A = A - np.outer(A[:, j] / A[i, j], A[i])
        A = np.delete(np.delete(A, i, 0), j, 1)
        del row_id[i], col_id[j]
    return steps


def partition_rcond(J: np.ndarray, n_ind: int) -> float:
    """How far J2 (the columns after the first ``n_ind``) is from singular, scale-free: the
    smallest pivot of J2's LU after every row of J = [J1 J2] is divided by its largest entry
    (1 for a J2 that is the whole row, → 0 as J2's share of a row vanishes or its rows become
    dependent); 0 where a whole row of J vanishes (shorter than :data:`RANK_TOL` times the
    longest: the rank is lost whatever the partition, as the N-four-bar's closure rows at
    its horizontal position).  ``solve="auto"`` leaves a partition below :data:`RCOND_ROBUST`."""
    J = np.asarray(J, float)
    if not np.all(np.isfinite(J)):
        return 0.0
    rn = np.abs(J).max(axis=1, initial=0.0)
    if np.any(rn <= RANK_TOL * rn.max(initial=0.0)) or not rn.size:  # a vanishing row: rank lost
        return 0.0
    J2 = J[:, n_ind:] / rn[:, None]
    if J2.shape[0] != J2.shape[1]:
        return 0.0
    import scipy.linalg as sla  # here: scipy costs a process ~0.2 s to import; only the reference path calls this

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", sla.LinAlgWarning)
        lu, _ = sla.lu_factor(J2, check_finite=False)
    return float(np.abs(np.diag(lu)).min(initial=1.0))
