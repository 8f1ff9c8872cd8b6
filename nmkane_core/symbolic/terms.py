"""What a numeric kernel evaluates: the derivation's matrices before any inverse.

Both kernels — the numpy reference (`nmkane_core.symbolic.reference`) and the compiled one
(`nmkane_core.kernel.codegen`) — evaluate the same expressions, in the order [u_I, u_D]:

* ``J``    = [J1  J2]  (17)–(18), m×n
* ``b``    = B1 u + B2 (14)–(15), the velocity part of the acceleration form (19)
* ``phin`` = φ (nonholonomic constraint values), ``psid`` = ψ̇, ``psi`` = ψ (holonomic)
* ``Q``, ``P`` the holonomic system (42); ``qdot`` = C u + D (1)
* ``energy``, ``viol`` (constraint values φ, ψ and monitors, in reporting order),
  ``outputs`` (extra reported quantities)

and then solve numerically: A = −J2⁻¹J1, B̂ = J2⁻¹(−b + s) with s the Baumgarte vector,
T = [A1; A2 Q], V̂ = [B̂; A2 P], T u̇ = V̂.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from .derivation import Derivation


@dataclass
class KernelTerms:
    derivation: Derivation
    args_t: sp.Symbol
    args_x: list  # q then u (model order)
    args_p: list
    J: sp.Matrix
    b: sp.Matrix
    phin: sp.Matrix
    psid: sp.Matrix
    psi: sp.Matrix
    Q: sp.Matrix
    P: sp.Matrix
    qdot: sp.Matrix
    energy: sp.Expr
    viol: sp.Matrix
    viol_names: tuple
    outputs: sp.Matrix
    output_names: tuple
    perm: list
    row_degree: list  # degree in u of each velocity-level constraint, 0 if not polynomial (row_degrees)

    @property
    def dims(self) -> dict:
        d = self.derivation
        return dict(
            N=d.model.n, M=d.m, MNH=d.m_nh, MH=d.m_h, PI=d.p, NV=len(self.viol_names), NO=len(self.output_names)
        )


def kernel_terms(d: Derivation) -> KernelTerms:
    md = d.model
    J = sp.Matrix.hstack(d.J1, d.J2) if d.m else sp.zeros(0, md.n)
    viol_exprs = list(md.nonholonomic.values()) + list(md.holonomic.values())
    viol_names = list(md.constraint_names)
    for k, v in md.monitors.items():
        if k not in viol_names:
            viol_names.append(k)
            viol_exprs.append(v)
    energy = sp.sympify(md.energy) if md.energy is not None else sp.Integer(0)
    S = _pythagorean_matrix
    return KernelTerms(
        derivation=d,
        args_t=md.t,
        args_x=list(md.q) + list(md.u),
        args_p=list(md.params),
        J=S(J),
        b=S(d.b),
        phin=S(d.phi_nh),
        psid=S(d.psi_dot),
        psi=S(d.psi),
        Q=S(d.Q),
        P=S(d.P),
        qdot=S(d.qdot),
        energy=pythagorean(energy),
        viol=S(sp.Matrix(viol_exprs)) if viol_exprs else sp.zeros(0, 1),
        viol_names=tuple(viol_names),
        outputs=sp.Matrix(list(md.outputs.values())) if md.outputs else sp.zeros(0, 1),
        output_names=tuple(md.outputs),
        perm=list(d.perm),
        row_degree=row_degrees(d),
    )


def row_degrees(d: Derivation) -> list:
    """How each row of φ = [φ_nh; ψ̇] is scaled for the kernels' estimate of J2's condition:
    its degree k ≥ 1 in u when it is a polynomial in u, else 0.

    The estimate is the pivot ratio min|pivot| / max|pivot| of J2's LU factors, which depends on
    the rows' relative sizes; the kernels (``rhs_ws`` in `nmkane_core.kernel.source.loops`) first
    bring the rows to comparable sizes:

    * a row of polynomial degree k > 1 (its gradient grows like |u|^(k−1)) is divided by
      max(1, |u|∞)^(k−1), so that a constraint quadratic in the speeds (the paper's (57))
      is flagged where its gradient degenerates (φ̇ → 0, cancellation) and not merely because
      the speeds are large; rows of degree 1 are left as they are.  (The paper's systems have
      only such rows: their estimates and thresholds do not depend on what follows.)
    * a row that is not a polynomial in u (k = 0: a square root — the speed along a path
      √(u1² + u2²) −, trigonometric, rational or exponential functions of the speeds) has no
      natural size to compare with, so it is made scale-free: divided by its own ∞-norm over
      the whole row [J1 J2] at the current state (the estimate is then the same for φ and c·φ
      and for any speeds).  Its share on the dependent speeds, max_j |J2_ij| / max_j |J_ij|,
      also bounds the estimate from above: a constraint whose gradient turns away from u_D
      (u2 − √(a² − u1²) as u1 → a, or √(u1² + u2²) − v with u_D = u2 as u2 → 0) makes J2
      singular even when J2 is 1×1, where the pivot ratio alone is always 1.  (A gradient that
      is not finite — a square root's argument at or past zero, a zero denominator — is not
      an estimate's business: the loops' finiteness checks end the run ``diverged`` there.)
    """
    return [_row_degree(e, d.u) for e in d.phi]


def _row_degree(e, u) -> int:
    try:
        return max(1, sp.Poly(sp.expand(e), *u).total_degree())
    except sp.PolynomialError:  # not a polynomial in u (sqrt, sin, exp, 1/u, ...)
        return 0


def pythagorean(e):
    """``e`` with every sum c·sin²a + c·cos²a replaced by c (same c, same a), bottom-up.

    Kane's mass matrices are full of such sums (Q[0,0] of the paper's Example 1 is
    I sin²φ + I cos²φ + M(ρ² sin²θ + ρ² cos²θ) = I + Mρ²): each one left in costs the kernels
    transcendental calls at every evaluation.  Exact, linear in the size of ``e`` (a
    structural match: no expansion, which can blow up, and no general ``trigsimp``, which
    costs about a second per model).
    """
    e = sp.sympify(e)
    if not (e.has(sp.sin) and e.has(sp.cos)):
        return e
    return e.replace(lambda a: a.is_Add, _pythagorean_add)


def _pythagorean_add(add):
    found: dict = {}  # (coefficient, argument) → {func: term index}
    terms = list(add.args)
    for i, term in enumerate(terms):
        factors = sp.Mul.make_args(term)
        for j, f in enumerate(factors):
            if f.is_Pow and f.exp == 2 and isinstance(f.base, (sp.sin, sp.cos)):
                key = (sp.Mul(*(factors[:j] + factors[j + 1 :])), f.base.args[0])
                found.setdefault(key, {}).setdefault(f.base.func, i)
                break
    drop, keep = set(), []
    for (c, _), where in found.items():
        if sp.sin in where and sp.cos in where:
            drop |= {where[sp.sin], where[sp.cos]}
            keep.append(c)
    if not drop:
        return add
    return sp.Add(*[t for i, t in enumerate(terms) if i not in drop], *keep)


def _pythagorean_matrix(m: sp.Matrix) -> sp.Matrix:
    return m.applyfunc(pythagorean) if m.shape[0] * m.shape[1] else m
