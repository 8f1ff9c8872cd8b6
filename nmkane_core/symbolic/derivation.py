"""The paper's procedure, steps 1–5, for any [`MechanicalModel`][nmkane_core.MechanicalModel].

Read beside Bajodah, Hodges & Chen (2005), Section 2 and 3:

* step 1 — acceleration form of the constraints (13), partition (16), J1, J2 (17)–(18),
  B1, B2 (14)–(15); holonomic constraints ψ(q,t) are differentiated once to the velocity
  level ψ̇ and then treated like nonholonomic ones (twice differentiated in all);
* (20) u̇_D = A u̇_I + B with A = −J2⁻¹J1, B = −J2⁻¹(B1 u + B2);
* step 2 — A1 = [−A  I] (22), A2 = [I  Aᵀ] (40);
* steps 3–4 — the holonomic system Q u̇ = P (41)–(43) comes with the model;
* step 5 — T = [A1; A2 Q], V = [B; A2 P] (44);
* Section 3 — Baumgarte terms: B̂ = B + J2⁻¹ Γ φ (108) for nonholonomic rows and
  B̂ = B + J2⁻¹ (Γ1 ψ̇ + Γ2 ψ) (113) for holonomic rows; V̂ = [B̂; A2 P] (110).

Everything here is symbolic and done once per model.  The numeric kernels never use
the symbolic inverses below (A, B, B̂, T, V): they evaluate J1, J2, B1 u + B2, Q and P and
solve numerically (see the numpy reference path and the kernel generator).  The
symbolic A, A1, A2, T, V exist to be inspected, printed in LaTeX and checked against the
paper's printed matrices.
"""

from __future__ import annotations

from functools import cached_property

import sympy as sp

from ..errors import NotDefined
from .model import MechanicalModel

__all__ = ["Derivation", "derive"]


def _column(exprs) -> sp.Matrix:
    exprs = [sp.sympify(e) for e in exprs]
    return sp.Matrix(len(exprs), 1, exprs)


def _jacobian(f: sp.Matrix, syms) -> sp.Matrix:
    """∂f/∂syms, differentiating each entry only by the symbols it contains (the same matrix
    as ``f.jacobian(syms)``; a large model's constraints each involve a few coordinates)."""
    syms = list(syms)
    if not f.shape[0] or not syms:
        return sp.zeros(f.shape[0], len(syms))
    where = {s: j for j, s in enumerate(syms)}
    flat = [sp.S.Zero] * (f.shape[0] * len(syms))
    for i, e in enumerate(f):
        for s in e.free_symbols:
            j = where.get(s)
            if j is not None:
                flat[i * len(syms) + j] = e.diff(s)
    return sp.Matrix(f.shape[0], len(syms), flat)


def _product(A: sp.Matrix, B: sp.Matrix) -> sp.Matrix:
    """A B, with the products of the identity and of zero matrices made without arithmetic (the
    kinematics q̇ = u of most mechanisms: C = I, D = 0) and other ones entry by entry over the
    nonzero terms only (the same sums as ``A * B``)."""
    if B.is_square and sp.eye(B.shape[0]) == B:
        return sp.Matrix(A)
    if B.is_zero_matrix:
        return sp.zeros(A.shape[0], B.shape[1])
    rows = [[k for k in range(A.shape[1]) if A[i, k] != 0] for i in range(A.shape[0])]
    flat = []
    for i in range(A.shape[0]):
        for j in range(B.shape[1]):
            flat.append(sp.Add(*[A[i, k] * B[k, j] for k in rows[i] if B[k, j] != 0]))
    return sp.Matrix(A.shape[0], B.shape[1], flat)


class Derivation:
    """Symbolic results of the procedure for one model (all ``sympy.Matrix``).

    Speeds are ordered ``u_perm = [u_I, u_D]`` in every matrix below (the paper's
    ordering (16)); ``perm`` maps that order back to the model's ``u``.  Built by
    [`derive`][nmkane_core.derive].

    Parameters
    ----------
    model : MechanicalModel
        The description to derive.

    Attributes
    ----------
    C, D : sympy.Matrix
        (1) q̇ = C u + D.
    phi : sympy.Matrix
        The velocity-level constraints [φ; ψ̇] whose acceleration form (13) is used.
    J1, J2 : sympy.Matrix
        (17)–(18) ∂φ/∂u_I and ∂φ/∂u_D.
    B1, B2 : sympy.Matrix
        (14)–(15) ∂φ/∂q C and ∂φ/∂q D + ∂φ/∂t.
    Gamma, Gamma1, Gamma2 : sympy.Matrix
        The Baumgarte gains as symbols (108), (113) (numeric kernels take them at run time).
    Q, P : sympy.Matrix
        (42) the holonomic system, speeds in the order [u_I, u_D].
    """

    def __init__(self, model: MechanicalModel):
        self.model = model
        md = model
        self.t = md.t
        self.q = sp.Matrix(md.q)
        self.u = sp.Matrix(md.u)
        if md.m:
            # column vectors even when empty (0×1): no u_independent declared, the partition is
            # picked numerically (every speed counts as dependent here; docs/closed-loops.md)
            self.u_I = sp.Matrix(md.u_independent) if md.u_independent else sp.zeros(0, 1)
            self.u_D = sp.Matrix(md.u_dependent)
        else:  # unconstrained (e.g. a minimal formulation): every speed is independent
            self.u_I = sp.Matrix(md.u)
            self.u_D = sp.zeros(0, 1)
        self.u_perm = sp.Matrix.vstack(self.u_I, self.u_D) if md.m else self.u_I
        self.perm = [list(md.u).index(s) for s in self.u_perm]
        self.p = len(self.u_I)

        # (1) kinematical differential equations
        self.C = md.C
        self.D = md.D
        self.qdot = _product(md.C, self.u) + md.D

        # constraint functions: φ (nonholonomic), ψ and ψ̇ (holonomic)
        # column vectors even when empty (0×1): a model may have only one kind of constraint
        self.phi_nh = _column(md.nonholonomic.values())
        self.psi = _column(md.holonomic.values())
        if self.psi.shape[0]:
            self.psi_dot = _product(_jacobian(self.psi, self.q), self.qdot) + self.psi.diff(self.t)
        else:
            self.psi_dot = sp.zeros(0, 1)
        self.m_nh = self.phi_nh.shape[0]
        self.m_h = self.psi.shape[0]
        self.m = self.m_nh + self.m_h
        # velocity-level constraints whose acceleration form (13) is used
        self.phi = sp.Matrix.vstack(self.phi_nh, self.psi_dot) if self.m else sp.zeros(0, 1)

        # (17)–(18) J1 = ∂φ/∂u_I, J2 = ∂φ/∂u_D
        if self.m:
            self.J1 = _jacobian(self.phi, self.u_I)
            self.J2 = _jacobian(self.phi, self.u_D)
            # (14)–(15) B1 = ∂φ/∂q C,  B2 = ∂φ/∂q D + ∂φ/∂t
            phi_q = _jacobian(self.phi, self.q)
            self.B1 = _product(phi_q, self.C)
            self.B2 = _product(phi_q, self.D) + self.phi.diff(self.t)
            # the velocity-dependent part of (19):  φ̇ = J1 u̇_I + J2 u̇_D + b
            self.b = _product(self.B1, self.u) + self.B2
        else:
            self.J1 = sp.zeros(0, self.p)
            self.J2 = sp.zeros(0, 0)
            self.B1 = sp.zeros(0, md.n)
            self.B2 = sp.zeros(0, 1)
            self.b = sp.zeros(0, 1)

        # the holonomic system (42), speeds in the order [u_I, u_D]
        self.Q = md.Q.extract(self.perm, self.perm)
        self.P = md.P.extract(self.perm, [0])

    # ------------------------------------------------------------ the Baumgarte terms (for display)
    # symbols, made when first asked for: the numeric kernels take the gains as runtime matrices
    # (a large model's Γ1 of symbols is m² of them)
    @cached_property
    def Gamma(self) -> sp.Matrix:
        """(104) Γ as a matrix of symbols."""
        return sp.Matrix(self.m_nh, self.m_nh, lambda i, j: sp.Symbol(f"Gamma_{i + 1}{j + 1}", real=True))

    @cached_property
    def Gamma1(self) -> sp.Matrix:
        """(112) Γ1 as a matrix of symbols."""
        return sp.Matrix(self.m_h, self.m_h, lambda i, j: sp.Symbol(f"Gamma1_{i + 1}{j + 1}", real=True))

    @cached_property
    def Gamma2(self) -> sp.Matrix:
        """(112) Γ2 as a matrix of symbols."""
        return sp.Matrix(self.m_h, self.m_h, lambda i, j: sp.Symbol(f"Gamma2_{i + 1}{j + 1}", real=True))

    @cached_property
    def s(self) -> sp.Matrix:
        """The stabilization vector: (104) Γ φ for nonholonomic rows, (112) Γ1 ψ̇ + Γ2 ψ for holonomic."""
        if not self.m:
            return sp.zeros(0, 1)
        return sp.Matrix.vstack(self.Gamma * self.phi_nh, self.Gamma1 * self.psi_dot + self.Gamma2 * self.psi)

    # ------------------------------------------------------------ (20)–(44)
    @cached_property
    def _J2_inv_rhs(self):
        """J2⁻¹ [J1 | b | s], solved symbolically by LU (small m only; for display)."""
        rhs = sp.Matrix.hstack(self.J1, self.b, self.s)
        rows, cols = self.J2.shape
        reason = "J2 is not square"
        if rows == cols:
            try:
                return self.J2.LUsolve(rhs)
            except ValueError as e:  # sympy: "The system is inconsistent." (J2 singular)
                reason = str(e)
        raise NotDefined(
            f"A = −J2⁻¹J1 (20) and the matrices built on it (B, B̂, A1, A2, T, V, V̂) are not "
            f"defined for this model: J2 is {rows} × {cols} and not invertible ({reason}) — its "
            f"constraint equations are redundant or singular there, and its runs use the "
            f"rank-robust solve (docs/closed-loops.md); J1, J2, B1, B2, Q and P are defined"
        )

    @cached_property
    def A(self) -> sp.Matrix:
        """(20) A = −J2⁻¹ J1."""
        if not self.m:
            return sp.zeros(0, self.p)
        return -self._J2_inv_rhs[:, : self.p]

    @cached_property
    def B(self) -> sp.Matrix:
        """(20) B = −J2⁻¹ (B1 u + B2)."""
        if not self.m:
            return sp.zeros(0, 1)
        return -self._J2_inv_rhs[:, self.p]

    @cached_property
    def B_hat(self) -> sp.Matrix:
        """(108)/(113) B̂ = B + J2⁻¹ [Γ φ; Γ1 ψ̇ + Γ2 ψ]."""
        if not self.m:
            return sp.zeros(0, 1)
        return self.B + self._J2_inv_rhs[:, self.p + 1]

    @cached_property
    def A1(self) -> sp.Matrix:
        """(22) A1 = [−A  I]."""
        return sp.Matrix.hstack(-self.A, sp.eye(self.m))

    @cached_property
    def A2(self) -> sp.Matrix:
        """(40) A2 = [I  Aᵀ]."""
        return sp.Matrix.hstack(sp.eye(self.p), self.A.T)

    @cached_property
    def T(self) -> sp.Matrix:
        """(44) T = [A1; A2 Q], the constrained generalized inertia matrix."""
        return sp.Matrix.vstack(self.A1, self.A2 * self.Q)

    @cached_property
    def V(self) -> sp.Matrix:
        """(44) V = [B; A2 P] (no stabilization)."""
        return sp.Matrix.vstack(self.B, self.A2 * self.P)

    @cached_property
    def V_hat(self) -> sp.Matrix:
        """(110) V̂ = [B̂; A2 P] (with the Baumgarte terms)."""
        return sp.Matrix.vstack(self.B_hat, self.A2 * self.P)

    # ----------------------------------------------------------- inspection
    NAMES = ("J1", "J2", "B1", "B2", "A", "B", "B_hat", "A1", "A2", "Q", "P", "T", "V", "V_hat")

    def matrix(self, name: str) -> sp.Matrix:
        """One derived matrix by its paper name.

        Parameters
        ----------
        name : str
            One of `NAMES`: ``J1``, ``J2``, ``B1``, ``B2``, ``A``, ``B``, ``B_hat``, ``A1``,
            ``A2``, ``Q``, ``P``, ``T``, ``V``, ``V_hat``.

        Returns
        -------
        sympy.Matrix

        Raises
        ------
        KeyError
            For an unknown name (the message lists the known ones).
        """
        if name not in self.NAMES:
            raise KeyError(f"unknown matrix {name!r}; known: {', '.join(self.NAMES)}")
        return getattr(self, name)

    def latex(self, name: str, simplify: bool = True) -> str:
        """LaTeX of one derived matrix, e.g. ``latex("A1")`` (for teaching panels).

        Parameters
        ----------
        name : str
            As for `matrix`.
        simplify : bool, optional
            Simplify each entry first (entries of 400 operations or more are left as they are).

        Returns
        -------
        str
            ``"A_1 = \\left[...\\right]"``.
        """
        mat = self.matrix(name)
        if simplify:
            mat = mat.applyfunc(lambda e: sp.simplify(e) if sp.count_ops(e) < 400 else e)
        sym = {
            "B_hat": r"\hat{B}",
            "V_hat": r"\hat{V}",
            "A1": "A_1",
            "A2": "A_2",
            "J1": "J_1",
            "J2": "J_2",
            "B1": "B_1",
            "B2": "B_2",
        }.get(name, name)
        return f"{sym} = {sp.latex(mat)}"


def derive(model: MechanicalModel) -> Derivation:
    """Run the paper's procedure on ``model`` (symbolic, once).

    Parameters
    ----------
    model : MechanicalModel
        The description.

    Returns
    -------
    Derivation
        Every matrix of steps 1–5 under its paper name; the inverses are computed when first
        asked for.
    """
    return Derivation(model)
