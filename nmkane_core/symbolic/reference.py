"""The plain numpy right-hand side: the reference the compiled kernel is checked against.

It follows the paper literally, step for step, with numpy/scipy linear algebra:
A = −J2⁻¹J1 and B̂ = B + J2⁻¹s by an LU solve (20), (108), (113); A1, A2 (22), (40);
T = [A1; A2 Q], V̂ = [B̂; A2 P] (44), (110); u̇ = T⁻¹V̂ by an LU solve (111).
Slow (a few tens of µs per call) but obviously right; used by tests and as a fallback.

Beside it, the rank-robust solve (``rhs(..., solve="robust")``, :func:`robust_solve` in
:mod:`nmkane_core.symbolic.robust`, design in ``docs/closed-loops.md``): the same equations
written as Gauss's principle in the mass metric — u̇ minimizes (u̇ − a)ᵀQ(u̇ − a) subject
to J u̇ = c, a = Q⁻¹P, c = −(B1 u + B2) + s — solved through a Cholesky factor of Q and a
Householder QR with column pivoting of L⁻¹Jᵀ, so that redundant constraints and an
instantaneous loss of rank (a mechanism passing a singular position) need no partition
and no invertible J2.  Where J2 is invertible it is the paper's u̇ (the same solution of
the same equations); ``solve="auto"`` keeps the paper's path there and re-picks the
partition by pivoting (Wehage & Haug 1982) or falls back to the robust solve where J2 is
ill-conditioned.  The mass-metric projection (:meth:`ReferenceKernel.project`) uses the
same pseudo-inverse.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
import sympy as sp

from ..errors import SingularMatrix
from .derivation import Derivation
from .robust import (  # noqa: F401 (re-exported: the reference's public names)
    CONSISTENCY_TOL,
    DECLARATION_RANK_TOL,
    RANK_TOL,
    RCOND_ROBUST,
    ConstraintsInconsistent,
    RobustSolution,
    cholesky_lower,
    fade_baumgarte,
    partition_by_pivoting,
    partition_rcond,
    qr_column_pivoting,
    robust_solve,
)
from .terms import kernel_terms


def pivot_rcond(lu: np.ndarray) -> float:
    """min|pivot| / max|pivot| of an LU factorization: the kernels' condition estimate."""
    piv = np.abs(np.diag(lu))
    if piv.size == 0:
        return 1.0
    big = piv.max()
    return float(piv.min() / big) if big > 0 else 0.0


class ReferenceKernel:
    """Lambdified terms and the paper's solve, in numpy (and the rank-robust one)."""

    def __init__(self, derivation: Derivation):
        kt = kernel_terms(derivation)
        self.terms = kt
        self.dims = kt.dims
        args = [kt.args_t, kt.args_x, kt.args_p]

        def lam(expr):
            return sp.lambdify(args, expr, modules="numpy", cse=True)

        self._J, self._b = lam(kt.J), lam(kt.b)
        self._phin, self._psid, self._psi = lam(kt.phin), lam(kt.psid), lam(kt.psi)
        self._Q, self._P, self._qdot = lam(kt.Q), lam(kt.P), lam(kt.qdot)
        self._energy, self._viol, self._outputs = lam(kt.energy), lam(kt.viol), lam(kt.outputs)
        d = derivation
        psi_q = d.psi.jacobian(d.q) if d.m_h else sp.zeros(0, d.model.n)
        self._psi_q = lam(psi_q)
        self._C_is_I = sp.eye(d.model.n) == d.model.C
        self.perm = np.array(kt.perm)
        self.max_rank: int | None = None
        self._order: list[int] | None = None  # the partition as a column order ([u_I, u_D]), "auto"
        self._mode: tuple[str, tuple[str, ...]] | None = None
        self.switches: list[dict] = []  # changes of solve or partition ("auto")
        self.last: RobustSolution | None = None  # the last robust solve (rank, dropped equations)
        self.reset()

    @staticmethod
    def _vec(v, size):
        return np.asarray(v, dtype=float).reshape(size)

    def _terms(self, t, x, p, G=None, G1=None, G2=None):
        """Q, P, J, b, s at a state, speeds in the order [u_I, u_D] (``perm``)."""
        d = self.dims
        N, M, MNH, MH = d["N"], d["M"], d["MNH"], d["MH"]
        G = np.zeros((MNH, MNH)) if G is None else np.asarray(G, float)
        G1 = np.zeros((MH, MH)) if G1 is None else np.asarray(G1, float)
        G2 = np.zeros((MH, MH)) if G2 is None else np.asarray(G2, float)
        Q = np.asarray(self._Q(t, x, p), float).reshape(N, N)
        P = self._vec(self._P(t, x, p), N)
        if not M:
            return Q, P, np.zeros((0, N)), np.zeros(0), np.zeros(0)
        J = np.asarray(self._J(t, x, p), float).reshape(M, N)
        b = self._vec(self._b(t, x, p), M)
        s = np.concatenate(
            [
                G @ self._vec(self._phin(t, x, p), MNH),
                G1 @ self._vec(self._psid(t, x, p), MH) + G2 @ self._vec(self._psi(t, x, p), MH),
            ]
        )
        return Q, P, J, b, s

    def _paper(self, Q, P, J, b, s, PI, x, out) -> dict:
        """(20)–(44), (110) numerically for J = [J1 J2] with J1 its first PI columns."""
        N, M = self.dims["N"], self.dims["M"]
        J1, J2 = J[:, :PI], J[:, PI:]
        out.update(J1=J1, J2=J2, b=b, s=s)
        if J2.shape[0] != J2.shape[1]:  # no partition, or redundant equations: no J2⁻¹
            out["rcond_J2"] = 0.0
            return out
        # the compiled kernel's row scaling for the condition estimate (kernel_terms.row_degrees)
        unorm = max(1.0, np.abs(np.asarray(x)[N:]).max(initial=0.0))
        deg = np.array(self.terms.row_degree, float)
        sc = unorm ** -(np.maximum(deg, 1.0) - 1.0)
        share = 1.0
        for i in np.flatnonzero(deg == 0):  # not polynomial in u: scale-free
            a = np.nan_to_num(np.abs(J[i]), nan=0.0, posinf=np.inf)
            big = a.max(initial=0.0)
            if 0.0 < big < np.inf:
                sc[i] = 1.0 / big
                share = min(share, a[PI:].max(initial=0.0) / big)
        with warnings.catch_warnings():  # an exactly singular J2 is reported by its estimate (0)
            warnings.simplefilter("ignore", sla.LinAlgWarning)
            lu = sla.lu_factor(sc[:, None] * J2, check_finite=False) if np.all(np.isfinite(J2)) else None
        rc_j2 = min(pivot_rcond(lu[0]), share) if lu is not None else 0.0
        out["rcond_J2"] = rc_j2
        if rc_j2 == 0.0:
            return out
        A = -sla.lu_solve(lu, sc[:, None] * J1)  # (20)
        B_hat = sla.lu_solve(lu, sc * (-b + s))  # (20), (108), (113)
        A1 = np.hstack([-A, np.eye(M)])  # (22)
        A2 = np.hstack([np.eye(PI), A.T])  # (40)
        T = np.vstack([A1, A2 @ Q])  # (44)
        V = np.concatenate([B_hat, A2 @ P])  # (110)
        out.update(A=A, B_hat=B_hat, A1=A1, A2=A2, T=T, V_hat=V)
        return out

    def matrices(self, t, x, p, G=None, G1=None, G2=None) -> dict:
        """J1, J2, A, B̂, A1, A2, T, V̂ evaluated numerically (for inspection and tests)."""
        Q, P, J, b, s = self._terms(t, x, p, G, G1, G2)
        out = {"Q": Q, "P": P}
        if self.dims["M"]:
            return self._paper(Q, P, J, b, s, self.dims["PI"], x, out)
        out.update(T=Q, V_hat=P, rcond_J2=1.0)
        return out

    def _solve_T(self, mats, t, rcond_min):
        T, V = mats["T"], mats["V_hat"]
        if not np.all(np.isfinite(T)):
            raise SingularMatrix("T", 0.0, t)
        lu = sla.lu_factor(T, check_finite=False)
        rc_t = pivot_rcond(lu[0])
        if rc_t <= rcond_min:
            raise SingularMatrix("T", rc_t, t)
        return sla.lu_solve(lu, V)  # (111)

    def _xdot(self, t, x, p, udot_perm):
        N = self.dims["N"]
        xdot = np.empty(2 * N)
        xdot[:N] = self._vec(self._qdot(t, x, p), N)
        xdot[N + self.perm] = udot_perm
        return xdot

    def rhs(
        self,
        t,
        x,
        p,
        G=None,
        G1=None,
        G2=None,
        rcond_min: float = 0.0,
        solve: str = "paper",
        rank_tol: float = RANK_TOL,
        consistency_tol: float = CONSISTENCY_TOL,
        rcond_robust: float = RCOND_ROBUST,
        fade: bool = False,
    ) -> np.ndarray:
        """ẋ = [C u + D; u̇].

        ``solve="paper"``: u̇ = T⁻¹V̂ with the declared partition; raises
        :class:`SingularMatrix` below ``rcond_min``.  ``solve="robust"``: :func:`robust_solve`
        (no partition needed; raises :class:`ConstraintsInconsistent` when the dependent
        equations miss by more than ``consistency_tol``, :class:`SingularMatrix` "Q" when Q is
        not positive definite).  ``solve="auto"``: the paper's path while J2's estimate is
        above ``rcond_robust``; below, the partition is re-picked by pivoting on J
        (:func:`partition_by_pivoting`) and, where no partition is well-conditioned (J has
        lost rank, or the equations are redundant), the robust solve; each change is
        appended to :attr:`switches`.  ``fade`` (with ``robust`` and ``auto``, as the compiled
        loops with a projection): the Baumgarte terms of vanishing rows fade
        (:func:`~nmkane_core.symbolic.robust.fade_baumgarte`)."""
        x = np.asarray(x, float)
        if solve == "paper":
            mats = self.matrices(t, x, p, G, G1, G2)
            if mats["rcond_J2"] <= rcond_min or "T" not in mats:
                raise SingularMatrix("J2", mats["rcond_J2"], t)
            return self._xdot(t, x, p, self._solve_T(mats, t, rcond_min))
        Q, P, J, b, s = self._terms(t, x, p, G, G1, G2)
        if fade:
            s = fade_baumgarte(J, s)
        if solve == "robust":
            return self._xdot(t, x, p, self._robust(t, Q, P, J, -b + s, rank_tol, consistency_tol))
        if solve != "auto":
            raise ValueError(f"solve={solve!r}; allowed: paper | robust | auto")
        M, PI = self.dims["M"], self.dims["PI"]
        if not M:
            return self._xdot(t, x, p, self._solve_T({"T": Q, "V_hat": P}, t, rcond_min))
        n = J.shape[1]
        n_ind = n - M
        threshold = max(rcond_robust, rcond_min)
        if self._order is None and n_ind == PI and n_ind > 0:
            self._order = list(range(n))  # the declared partition, first
        if self._order is not None and partition_rcond(J[:, self._order], n_ind) > threshold:
            return self._paper_auto(t, x, p, Q, P, J, b, s, n_ind, rcond_min)
        dep, _, rank = partition_by_pivoting(J, rank_tol)
        if rank == M and n_ind >= 0:  # J has full rank: re-pick the partition (Wehage & Haug)
            order = [j for j in range(n) if j not in dep] + sorted(dep)
            if partition_rcond(J[:, order], n_ind) > threshold:
                self._order = order
                return self._paper_auto(t, x, p, Q, P, J, b, s, n_ind, rcond_min)
        self._note(t, "robust", [])
        return self._xdot(t, x, p, self._robust(t, Q, P, J, -b + s, rank_tol, consistency_tol))

    def _paper_auto(self, t, x, p, Q, P, J, b, s, n_ind, rcond_min):
        order = self._order
        assert order is not None
        mats = self._paper(Q[np.ix_(order, order)], P[order], J[:, order], b, s, n_ind, x, {})
        if "T" not in mats:
            raise SingularMatrix("J2", mats["rcond_J2"], t)
        self._note(t, "paper", order[n_ind:])
        u = np.empty(J.shape[1])
        u[order] = self._solve_T(mats, t, rcond_min)
        return self._xdot(t, x, p, u)

    def _robust(self, t, Q, P, J, c, rank_tol, consistency_tol):
        try:
            if self.max_rank is None:
                self.max_rank = robust_solve(Q, P, J, c, DECLARATION_RANK_TOL).rank
            sol = robust_solve(Q, P, J, c, rank_tol, self.max_rank)
        except SingularMatrix as e:
            raise SingularMatrix(e.matrix, e.rcond, t) from None
        self.last = sol
        if sol.residual > consistency_tol:
            names = self.terms.derivation.model.constraint_names
            raise ConstraintsInconsistent(t, sol.rank, sol.m, [names[i] for i in sol.dependent], sol.residual)
        return sol.udot

    def _note(self, t, how, dep_perm):
        names = [str(self.terms.derivation.u_perm[i]) for i in dep_perm]
        key = (how, tuple(names))
        if key != self._mode:
            if self._mode is not None:
                self.switches.append({"t": float(t), "solve": how, "u_dependent": names})
            self._mode = key

    def reset(self) -> None:
        """Forget the partition picked, the rank found and the switches of a previous run."""
        self._order, self._mode, self.last = None, None, None
        self.switches = []
        self.max_rank = self._declared_rank

    @property
    def _declared_rank(self) -> int | None:
        """n − p when the model declares its independent speeds (redundant or not), else None
        (the rank is then taken at the first robust solve, from the equilibrated QR with
        :data:`DECLARATION_RANK_TOL`: the default state, in a run)."""
        p = len(self.terms.derivation.model.u_independent)
        return self.dims["N"] - p if p else None

    def constraint_report(self, t, x, p, tol: float = DECLARATION_RANK_TOL) -> dict:
        """The constraints' rank at a state and a partition picked there (Wehage & Haug).

        ``rank`` of J = ∂[φ; ψ̇]/∂u, ``independent_speeds`` = n − rank, ``redundant``: the
        equations dependent on the others there (names), ``u_dependent``/``u_independent``:
        the speeds picked by complete pivoting on J, ``q_dependent``: the coordinates picked
        by complete pivoting on ∂ψ/∂q (the holonomic rows), ``rcond``: the smallest pivot of
        the equilibrated QR (how far from losing rank)."""
        x = np.asarray(x, float)
        md = self.terms.derivation.model
        Q, P, J, b, s = self._terms(t, x, p)
        u_names = [str(v) for v in self.terms.derivation.u_perm]
        names = list(md.constraint_names)
        sol = robust_solve(Q, P, J, -b + s, tol)
        dep, _, _ = partition_by_pivoting(J, tol)
        out = {
            "rank": sol.rank,
            "m": sol.m,
            "independent_speeds": len(u_names) - sol.rank,
            "redundant": [names[i] for i in sol.dependent],
            "u_dependent": [u_names[j] for j in sorted(dep)],
            "u_independent": [u_names[j] for j in range(len(u_names)) if j not in dep],
            "rcond": sol.rcond,
        }
        MH = self.dims["MH"]
        if MH:
            psi_q = np.asarray(self._psi_q(t, x, p), float).reshape(MH, self.dims["N"])
            qdep, _, _ = partition_by_pivoting(psi_q, tol)
            q_names = [str(v) for v in md.q]
            out["q_dependent"] = [q_names[j] for j in sorted(qdep)]
        else:
            out["q_dependent"] = []
        return out

    def _model_order(self, Q, J):
        """Q and J with the speeds in the model's order (the kernels use [u_I, u_D])."""
        n = self.dims["N"]
        Qm = np.empty((n, n))
        Qm[np.ix_(self.perm, self.perm)] = Q
        Jm = np.empty_like(J)
        Jm[:, self.perm] = J
        return Qm, Jm

    def project(self, t, x, p, iterations: int = 4, tol: float = 1e-14, rank_tol: float = RANK_TOL) -> np.ndarray:
        """The state moved onto the constraints, in the mass metric (Yoon et al. 1994 style):
        positions by Newton steps δq = −W⁻¹ψ_qᵀ(ψ_q W⁻¹ψ_qᵀ)⁺ψ, then the speeds by
        δu = −Q⁻¹Jᵀ(J Q⁻¹Jᵀ)⁺[φ; ψ̇] (Newton, for constraints nonlinear in u) — every
        pseudo-inverse through :func:`robust_solve` (rank-robust: redundant equations and a
        singular position need nothing else).  W = Q when q̇ = u (C = I), else the identity."""
        d = self.dims
        N, MH, M = d["N"], d["MH"], d["M"]
        x = np.array(x, float, copy=True)
        if not M:
            return x
        zero = np.zeros(N)
        for _ in range(iterations if MH else 0):
            psi = self._vec(self._psi(t, x, p), MH)
            if np.abs(psi).max(initial=0.0) <= tol:
                break
            psi_q = np.asarray(self._psi_q(t, x, p), float).reshape(MH, N)
            if self._C_is_I:
                Q, _, J, _, _ = self._terms(t, x, p)
                W = self._model_order(Q, J)[0]
            else:
                W = np.eye(N)
            x[:N] += robust_solve(W, zero, psi_q, -psi, rank_tol, self.max_rank if not d["MNH"] else None).udot
        for _ in range(iterations):
            r = np.concatenate([self._vec(self._phin(t, x, p), d["MNH"]), self._vec(self._psid(t, x, p), MH)])
            if np.abs(r).max(initial=0.0) <= tol:
                break
            Q, _, J, _, _ = self._terms(t, x, p)
            Qm, Jm = self._model_order(Q, J)
            x[N:] += robust_solve(Qm, zero, Jm, -r, rank_tol, self.max_rank).udot
        return x

    def tangent(self, t, x, p, dx, rank_tol: float = RANK_TOL) -> np.ndarray:
        """``dx`` (a change of the state, e.g. an integrator's error estimate) without its
        components along the constraint normals, in the mass metric: the part the post-step
        projection does not remove.  Near a singular position the error estimate is
        dominated by those components (the equations amplify the branch's asymmetry); an
        adaptive step control that sees them shrinks the step onto the singular point, as the
        compiled adaptive run of A02 does (docs/closed-loops.md)."""
        d = self.dims
        N, MH, M = d["N"], d["MH"], d["M"]
        dx = np.array(dx, float, copy=True)
        if not M:
            return dx
        Q, _, J, _, _ = self._terms(t, x, p)
        Qm, Jm = self._model_order(Q, J)
        zero = np.zeros(N)
        if MH:
            psi_q = np.asarray(self._psi_q(t, x, p), float).reshape(MH, N)
            W = Qm if self._C_is_I else np.eye(N)
            cap = self.max_rank if not d["MNH"] else None
            dx[:N] += robust_solve(W, zero, psi_q, -psi_q @ dx[:N], rank_tol, cap).udot
        dx[N:] += robust_solve(Qm, zero, Jm, -Jm @ dx[N:], rank_tol, self.max_rank).udot
        return dx

    def energy(self, t, x, p) -> float:
        return float(self._energy(t, x, p))

    def violation(self, t, x, p) -> np.ndarray:
        return self._vec(self._viol(t, x, p), self.dims["NV"])

    def outputs(self, t, x, p) -> np.ndarray:
        return self._vec(self._outputs(t, x, p), self.dims["NO"])

    def constraint_residuals(self, t, x, p) -> dict:
        """φ, ψ̇, ψ at a state (used to check and complete initial states)."""
        d = self.dims
        return {
            "phin": self._vec(self._phin(t, x, p), d["MNH"]),
            "psid": self._vec(self._psid(t, x, p), d["MH"]),
            "psi": self._vec(self._psi(t, x, p), d["MH"]),
        }


def integrate_reference(
    kernel: ReferenceKernel,
    x0,
    p,
    dt: float,
    nsteps: int,
    tableau,
    G=None,
    G1=None,
    G2=None,
    project: bool = False,
    **options,
) -> tuple[np.ndarray, np.ndarray]:
    """A plain-Python fixed-step Runge–Kutta run with the reference right-hand side.

    The same tableau data as the compiled loop; used by the tests to check that compiled
    and reference trajectories agree.  ``options`` go to :meth:`ReferenceKernel.rhs`
    (``solve="robust"`` ...); ``project=True`` moves each step's state onto the
    constraints (:meth:`ReferenceKernel.project`).  Returns (t, x) with one row per step.
    """
    A, b, c = tableau.A, tableau.b, tableau.c
    options.setdefault("fade", project)  # as the compiled loops with a projection
    x = np.array(x0, float)
    ts, xs = [0.0], [x.copy()]
    for k in range(nsteps):
        t = k * dt
        K: list = []
        for i in range(len(c)):
            xi = x + dt * sum((A[i, j] * K[j] for j in range(i)), np.zeros_like(x))
            K.append(kernel.rhs(t + c[i] * dt, xi, p, G, G1, G2, **options))
        x = x + dt * sum(bi * ki for bi, ki in zip(b, K, strict=True))
        if project:
            x = kernel.project((k + 1) * dt, x, p)
        ts.append((k + 1) * dt)
        xs.append(x.copy())
    return np.array(ts), np.array(xs)


def integrate_reference_adaptive(
    kernel: ReferenceKernel,
    x0,
    p,
    t_final: float,
    tableau,
    G=None,
    G1=None,
    G2=None,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    h0: float = 1e-3,
    project: bool = True,
    tangent: bool = True,
    **options,
) -> tuple[np.ndarray, np.ndarray, int]:
    """An embedded Runge–Kutta run with the compiled adaptive loop's step control (weighted
    RMS error with atol + rtol·max(|x|, |x_new|), h ← h·clamp(0.9·err^(−1/(q+1)), 0.2, 5)),
    the projection after each accepted step (``project``) and, with ``tangent``, the error
    estimate without its components along the constraint normals
    (:meth:`ReferenceKernel.tangent`, as Simbody projects its error estimate): near a
    singular position those components are the branch's amplified asymmetry, which the
    projection removes anyway and which would otherwise drive the step onto the singular
    point.  Returns (t, x, rejected steps)."""
    A, b, c, E = tableau.A, tableau.b, tableau.c, tableau.E
    options.setdefault("fade", project)  # as the compiled loops with a projection
    exponent = 1.0 / (tableau.error_order + 1)
    t, h, x = 0.0, h0, np.array(x0, float)
    ts, xs, rejected = [0.0], [x.copy()], 0
    while t < t_final:
        h = min(h, t_final - t)
        K: list = []
        for i in range(len(c)):
            xi = x + h * sum((A[i, j] * K[j] for j in range(i)), np.zeros_like(x))
            K.append(kernel.rhs(t + c[i] * h, xi, p, G, G1, G2, **options))
        xn = x + h * sum(bi * ki for bi, ki in zip(b, K, strict=True))
        delta = h * sum(ei * ki for ei, ki in zip(E, K, strict=True))
        if tangent:
            delta = kernel.tangent(t + h, xn, p, delta)
        err = float(np.sqrt(np.mean((delta / (atol + rtol * np.maximum(np.abs(x), np.abs(xn)))) ** 2)))
        if err <= 1.0:
            t = t_final if t_final - t - h <= 1e-12 * t_final else t + h
            x = kernel.project(t, xn, p) if project else xn
            ts.append(t)
            xs.append(x.copy())
        else:
            rejected += 1
        h *= min(5.0, max(0.2, 0.9 * err**-exponent)) if err > 0 else 5.0
    return np.array(ts), np.array(xs), rejected
