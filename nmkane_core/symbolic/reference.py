"""The plain numpy right-hand side: the reference the compiled kernel is checked against.

It follows the paper literally, step for step, with numpy/scipy linear algebra:
A = −J2⁻¹J1 and B̂ = B + J2⁻¹s by an LU solve (20), (108), (113); A1, A2 (22), (40);
T = [A1; A2 Q], V̂ = [B̂; A2 P] (44), (110); u̇ = T⁻¹V̂ by an LU solve (111).
Slow (a few tens of µs per call) but obviously right; used by tests and as a fallback.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import sympy as sp

from ..errors import SingularMatrix
from .derivation import Derivation
from .terms import kernel_terms


def pivot_rcond(lu: np.ndarray) -> float:
    """min|pivot| / max|pivot| of an LU factorization: the kernels' condition estimate."""
    piv = np.abs(np.diag(lu))
    if piv.size == 0:
        return 1.0
    big = piv.max()
    return float(piv.min() / big) if big > 0 else 0.0


class ReferenceKernel:
    """Lambdified terms and the paper's solve, in numpy."""

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
        self.perm = np.array(kt.perm)

    @staticmethod
    def _vec(v, size):
        return np.asarray(v, dtype=float).reshape(size)

    def matrices(self, t, x, p, G=None, G1=None, G2=None) -> dict:
        """J1, J2, A, B̂, A1, A2, T, V̂ evaluated numerically (for inspection and tests)."""
        d = self.dims
        N, M, MNH, MH, PI = d["N"], d["M"], d["MNH"], d["MH"], d["PI"]
        G = np.zeros((MNH, MNH)) if G is None else np.asarray(G, float)
        G1 = np.zeros((MH, MH)) if G1 is None else np.asarray(G1, float)
        G2 = np.zeros((MH, MH)) if G2 is None else np.asarray(G2, float)
        Q = np.asarray(self._Q(t, x, p), float).reshape(N, N)
        P = self._vec(self._P(t, x, p), N)
        out = {"Q": Q, "P": P}
        if M:
            J = np.asarray(self._J(t, x, p), float).reshape(M, N)
            b = self._vec(self._b(t, x, p), M)
            s = np.concatenate(
                [
                    G @ self._vec(self._phin(t, x, p), MNH),
                    G1 @ self._vec(self._psid(t, x, p), MH) + G2 @ self._vec(self._psi(t, x, p), MH),
                ]
            )
            J1, J2 = J[:, :PI], J[:, PI:]
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
            lu = sla.lu_factor(sc[:, None] * J2, check_finite=False) if np.all(np.isfinite(J2)) else None
            rc_j2 = min(pivot_rcond(lu[0]), share) if lu is not None else 0.0
            out.update(J1=J1, J2=J2, b=b, s=s, rcond_J2=rc_j2)
            if rc_j2 == 0.0:
                return out
            A = -sla.lu_solve(lu, sc[:, None] * J1)  # (20)
            B_hat = sla.lu_solve(lu, sc * (-b + s))  # (20), (108), (113)
            A1 = np.hstack([-A, np.eye(M)])  # (22)
            A2 = np.hstack([np.eye(PI), A.T])  # (40)
            T = np.vstack([A1, A2 @ Q])  # (44)
            V = np.concatenate([B_hat, A2 @ P])  # (110)
            out.update(A=A, B_hat=B_hat, A1=A1, A2=A2, T=T, V_hat=V)
        else:
            out.update(T=Q, V_hat=P, rcond_J2=1.0)
        return out

    def rhs(self, t, x, p, G=None, G1=None, G2=None, rcond_min: float = 0.0) -> np.ndarray:
        """ẋ = [C u + D; T⁻¹ V̂]; raises `SingularMatrix` below ``rcond_min``."""
        x = np.asarray(x, float)
        N = self.dims["N"]
        mats = self.matrices(t, x, p, G, G1, G2)
        if mats["rcond_J2"] <= rcond_min or "T" not in mats:
            raise SingularMatrix("J2", mats["rcond_J2"], t)
        T, V = mats["T"], mats["V_hat"]
        if not np.all(np.isfinite(T)):
            raise SingularMatrix("T", 0.0, t)
        lu = sla.lu_factor(T, check_finite=False)
        rc_t = pivot_rcond(lu[0])
        if rc_t <= rcond_min:
            raise SingularMatrix("T", rc_t, t)
        udot_perm = sla.lu_solve(lu, V)  # (111)
        xdot = np.empty(2 * N)
        xdot[:N] = self._vec(self._qdot(t, x, p), N)
        xdot[N + self.perm] = udot_perm
        return xdot

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
    kernel: ReferenceKernel, x0, p, dt: float, nsteps: int, tableau, G=None, G1=None, G2=None
) -> tuple[np.ndarray, np.ndarray]:
    """A plain-Python fixed-step Runge–Kutta run with the reference right-hand side.

    The same tableau data as the compiled loop; used by the tests to check that compiled
    and reference trajectories agree.  Returns (t, x) with one row per step.
    """
    A, b, c = tableau.A, tableau.b, tableau.c
    x = np.array(x0, float)
    ts, xs = [0.0], [x.copy()]
    for k in range(nsteps):
        t = k * dt
        K: list = []
        for i in range(len(c)):
            xi = x + dt * sum((A[i, j] * K[j] for j in range(i)), np.zeros_like(x))
            K.append(kernel.rhs(t + c[i] * dt, xi, p, G, G1, G2))
        x = x + dt * sum(bi * ki for bi, ki in zip(b, K, strict=True))
        ts.append((k + 1) * dt)
        xs.append(x.copy())
    return np.array(ts), np.array(xs)
