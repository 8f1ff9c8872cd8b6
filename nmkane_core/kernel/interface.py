"""The compiled loops' interface, defined once: their arguments and their work arrays.

The loops (``integrate_fixed``, ``integrate_adaptive`` of the compiled core,
``kernel/csrc/loops.c``) take one record of arguments each, :class:`FixedArgs` and
:class:`AdaptiveArgs`, every field with its kind beside it (a float64 vector or matrix, an int64
vector, a scalar).  From that one definition come

* the C records the loops read (:mod:`nmkane_core.kernel.core` generates ``nmk_fixed_args`` and
  ``nmk_adaptive_args``, an array field as its pointer and its shape) and their ctypes twins;
* the calls: the drivers build the record by name and call ``kernel.integrate_fixed(*args)``.

The flat work arrays of the right-hand side (:data:`WORKSPACE`) and of the projections
(:data:`PROJECTION_SCRATCH`) are laid out here too, as tables of named blocks with sizes
written in the model's dimensions; the generator turns them into the offsets each model's
record carries.  Status codes and the ``stats`` layout are plain constants in
:mod:`nmkane_core.kernel.constants`.
"""

from __future__ import annotations

import ast
from collections.abc import Callable
from typing import Annotated, Any, NamedTuple, Protocol

import numpy as np

__all__ = [
    "CompiledModel",
    "FixedArgs",
    "AdaptiveArgs",
    "LOOPS",
    "WORKSPACE",
    "PROJECTION_SCRATCH",
    "layout",
]

# the kinds of the fields (kernel.core.loop_kinds: an array is passed as its pointer and shape)
VEC = "float64[::1]"
MAT = "float64[:, ::1]"
FLOAT = "float64"
INT = "int64"
IVEC = "int64[::1]"
PROJ = "proj"  # int64[::1] with a projection, None without (see ProjectionOptions)


class FixedArgs(NamedTuple):
    """``integrate_fixed``'s arguments, in order: steps k0 … k1−1 of a run of ``nsteps`` steps."""

    x: Annotated[np.ndarray, VEC]  # state, advanced in place
    t0: Annotated[float, FLOAT]
    dt: Annotated[float, FLOAT]
    t_final: Annotated[float, FLOAT]
    k0: Annotated[int, INT]
    k1: Annotated[int, INT]
    nsteps: Annotated[int, INT]
    every: Annotated[int, INT]  # keep every ``every``-th state
    p: Annotated[np.ndarray, VEC]  # parameters
    G: Annotated[np.ndarray, MAT]  # Γ
    G1: Annotated[np.ndarray, MAT]  # Γ1
    G2: Annotated[np.ndarray, MAT]  # Γ2
    TA: Annotated[np.ndarray, MAT]  # tableau A, b, c
    TB: Annotated[np.ndarray, VEC]
    TC: Annotated[np.ndarray, VEC]
    rcond_min: Annotated[float, FLOAT]  # stop threshold of the rcond estimates
    drift_limit: Annotated[float, FLOAT]  # stop (STATUS_DRIFTED) where |E − E0| exceeds this (inf: never)
    violation_limit: Annotated[float, FLOAT]  # … or where a reported violation exceeds this
    solve: Annotated[int, INT]  # the constraint solve: 0 the paper's, 1 rank-robust, 2 auto (kernels with ROBUST)
    rank_tol: Annotated[float, FLOAT]  # the robust solve's rank threshold (symbolic.robust.RANK_TOL)
    max_rank: Annotated[int, INT]  # the model's number of independent equations (n − p, or the rank found)
    consistency_tol: Annotated[float, FLOAT]  # above this relative residual J u̇ = c is inconsistent
    rcond_robust: Annotated[float, FLOAT]  # "auto" leaves a partition whose J2 estimate falls below this
    order: Annotated[np.ndarray, IVEC]  # the partition as a column order [u_I, u_D] of J, advanced in place
    solve_log: Annotated[np.ndarray, MAT]  # records of the solve's changes (kernel.constants LOG_*)
    proj: Annotated[np.ndarray | None, PROJ]
    near_proj: Annotated[np.ndarray | None, PROJ]  # without proj: the projection of steps near a singular position
    out_t: Annotated[np.ndarray, VEC]  # output rows
    out_x: Annotated[np.ndarray, MAT]
    out_E: Annotated[np.ndarray, VEC]
    out_V: Annotated[np.ndarray, MAT]
    out_F: Annotated[np.ndarray, MAT]  # constraint forces F_c = Q u̇ − P of each row (model order); 0 rows: off
    out_L: Annotated[np.ndarray, MAT]  # multipliers λ of each row (F_c = Jᵀλ)
    row: Annotated[int, INT]  # next free output row
    pending: Annotated[int, INT]  # a row whose forces are still to come (the next step's first stage), or −1
    stats: Annotated[np.ndarray, VEC]  # running statistics (STATS_*), updated in place


class AdaptiveArgs(NamedTuple):
    """``integrate_adaptive``'s arguments, in order: from t until t_final, a full output
    buffer, or ``max_steps`` attempts."""

    x: Annotated[np.ndarray, VEC]  # state, advanced in place
    t: Annotated[float, FLOAT]
    t_final: Annotated[float, FLOAT]
    h: Annotated[float, FLOAT]  # first step to try
    rtol: Annotated[float, FLOAT]
    atol: Annotated[float, FLOAT]
    hmin: Annotated[float, FLOAT]
    hmax: Annotated[float, FLOAT]
    max_steps: Annotated[int, INT]  # attempts allowed in this call
    every: Annotated[int, INT]
    accepted: Annotated[int, INT]  # accepted steps so far (for ``every``)
    p: Annotated[np.ndarray, VEC]
    G: Annotated[np.ndarray, MAT]
    G1: Annotated[np.ndarray, MAT]
    G2: Annotated[np.ndarray, MAT]
    TA: Annotated[np.ndarray, MAT]  # tableau A, b, E = b − b̂, c
    TB: Annotated[np.ndarray, VEC]
    TE: Annotated[np.ndarray, VEC]
    TC: Annotated[np.ndarray, VEC]
    err_exp: Annotated[float, FLOAT]  # step-control exponent 1/(q+1)
    rcond_min: Annotated[float, FLOAT]
    drift_limit: Annotated[float, FLOAT]
    violation_limit: Annotated[float, FLOAT]
    solve: Annotated[int, INT]  # the constraint solve: 0 the paper's, 1 rank-robust, 2 auto (kernels with ROBUST)
    rank_tol: Annotated[float, FLOAT]  # the robust solve's rank threshold (symbolic.robust.RANK_TOL)
    max_rank: Annotated[int, INT]  # the model's number of independent equations (n − p, or the rank found)
    consistency_tol: Annotated[float, FLOAT]  # above this relative residual J u̇ = c is inconsistent
    rcond_robust: Annotated[float, FLOAT]  # "auto" leaves a partition whose J2 estimate falls below this
    order: Annotated[np.ndarray, IVEC]  # the partition as a column order [u_I, u_D] of J, advanced in place
    solve_log: Annotated[np.ndarray, MAT]  # records of the solve's changes (kernel.constants LOG_*)
    proj: Annotated[np.ndarray | None, PROJ]
    near_proj: Annotated[np.ndarray | None, PROJ]  # without proj: the projection of steps near a singular position
    out_t: Annotated[np.ndarray, VEC]  # output buffer (its length caps the rows of a call)
    out_x: Annotated[np.ndarray, MAT]
    out_E: Annotated[np.ndarray, VEC]
    out_V: Annotated[np.ndarray, MAT]
    out_F: Annotated[np.ndarray, MAT]  # constraint forces of each row (model order); 0 rows: off
    out_L: Annotated[np.ndarray, MAT]  # multipliers of each row
    pending: Annotated[int, INT]  # a row whose forces are those of the starting state, or −1
    stats: Annotated[np.ndarray, VEC]


class CompiledModel(Protocol):
    """What the integrators and the run layer use of a compiled kernel: the seam between
    ``integrate/`` (and ``run/``) and ``kernel/``.  :class:`~nmkane_core.kernel.cmodel.CModel`
    is the one implementation: a model's description and library bound to the compiled core.

    Sizes: ``N`` speeds (and coordinates), ``M`` constraint equations (``MNH`` nonholonomic,
    ``MH`` holonomic), ``PI`` independent speeds of the declared partition, ``NV`` reported
    violations, ``NO`` outputs, ``PERM`` the speeds' order [u_I, u_D] in model order; ``ROBUST``:
    the rank-robust solve is compiled in (every model with constraints), ``MAX_RANK_DEFAULT`` its
    rank cap; ``DECLARED``: J's columns are a declared, non-redundant partition, whose paper's
    solve is the paper's own path; ``KN``: the size of the block of the kinematics' C whose
    estimate is computed (0: C is constant); ``ORC``, ``OQ``: the work array's offsets of the
    condition estimates and of Q.  The loops take their records (:class:`FixedArgs`,
    :class:`AdaptiveArgs`) as positional arguments; the rest are the right-hand side and the
    diagnostics at given states."""

    __name__: str
    N: int
    M: int
    MNH: int
    MH: int
    PI: int
    NV: int
    NO: int
    PERM: np.ndarray
    ROBUST: bool
    DECLARED: bool
    KN: int
    MAX_RANK_DEFAULT: int
    ORC: int
    OQ: int
    integrate_fixed: Callable[..., tuple[int, int, int, int]]  # *FixedArgs -> status, k, row, pending
    integrate_adaptive: Callable[..., tuple[int, float, float, int, int, int, int]]  # *AdaptiveArgs
    make_workspace: Callable[[], np.ndarray]
    rhs_ws: Callable[..., None]  # (t, x, p, G, G1, G2, K, row, w): ẋ into K[row]
    rhs_bound: Callable[..., Callable[[float, np.ndarray], None]]  # (p, G, G1, G2, K, w) -> f(t, x): ẋ into K[0]
    rhs: Callable[..., np.ndarray]  # (t, x, p, G, G1, G2) -> ẋ
    diagnostics: Callable[..., float]  # (t, x, p, viol) -> E, violations into viol
    diagnostics_rows: Callable[..., None]  # (ts, xs, p, E, V)
    outputs_rows: Callable[..., None]  # (ts, xs, p, O)
    forces_rows: Callable[..., None]  # (ts, xs, p, G, G1, G2, F, L)
    state_terms: Callable[..., Any]  # (t, x, p) -> the model's matrices at a state
    solve_setup: Callable[..., None]
    # the loops' bookkeeping of the rank-robust solve after one right-hand side (the scipy adapter
    # calls it between scipy's steps; named with the underscore of loops.py, where it is internal)
    _robust_outcome: Callable[..., int]
    project_state: Callable[..., Any]
    project_state_robust: Callable[..., Any]
    specialize: Callable[..., None]  # (wait=False): the model's specialised build, in the background


#: the compiled loops by name, and the record of each one's arguments
LOOPS: dict[str, Any] = {"integrate_fixed": FixedArgs, "integrate_adaptive": AdaptiveArgs}


# ---------------------------------------------------------------------------- work arrays
# Each table lists named blocks in order with their sizes as expressions in the model's
# dimensions: N speeds, M constraints (MNH nonholonomic, MH holonomic), PI independent speeds of
# the paper's solve (N − M); NR, MR = N, M in kernels with the rank-robust solve (else 0), RB = 1
# there (else 0); KN the size of the block of the kinematics' C that varies along the motion (0: none).
# A block's name is the offset of its first entry; the generator writes every offset (and the
# total, WSIZE / PS_SIZE) into the kernel as a constant.

#: the right-hand side's flat work array (``init_workspace`` in csrc/loops.c)
WORKSPACE: tuple[tuple[str, str, str], ...] = (
    ("OJ", "M * N", "J = [J1 J2] (17)–(18), rows of [φ; ψ̇], speeds in the order [u_I, u_D]"),
    ("OB", "M", "b = B1 u + B2 (14)–(15)"),
    ("OPHIN", "MNH", "φ, the nonholonomic constraint values"),
    ("OPSID", "MH", "ψ̇"),
    ("OPSI", "MH", "ψ"),
    ("OQ", "N * N", "Q (42), [u_I, u_D] order"),
    ("OP", "N", "P (42)"),
    ("OQD", "N", "q̇ = C u + D (1)"),
    ("OR", "M * (PI + 1 + RB)", "R = [−J1 | −b + s] → [A | B̂] (20), (108), (113) (with ROBUST: and | s → J2⁻¹s)"),
    ("OW", "N * PI", "W = Q A2ᵀ"),
    ("OMR", "PI * PI", "A2 Q A2ᵀ"),
    ("OY", "N * (1 + RB)", "P − Q_{·D} B̂ (with ROBUST: and −Q_{·D} J2⁻¹s, by rows)"),
    ("OUI", "PI * (1 + RB)", "A2 (P − Q_{·D} B̂) → u̇_I (with ROBUST: and the Baumgarte terms' part, by rows)"),
    ("ORC", "3", "(rcond J2, rcond T, the kinematics' estimate: 1 where C is constant)"),
    ("OPSQ", "MH * N", "∂ψ/∂q (positions)"),
    ("OC", "N * N", "C (positions)"),
    ("OCK", "KN * KN", "C's varying block, its rows normalized, and its LU (the kinematics' estimate)"),
    ("OFLAG", "1", "1.0: this evaluation's constraint forces are wanted (J2, Q, P are kept for them)"),
    ("OJ2C", "M * M", "a copy of J2 made before its LU, for the multipliers"),
    ("OQC", "N * N", "a copy of Q of that evaluation (the step's later stages overwrite OQ)"),
    ("OPC", "N", "a copy of P of it"),
    ("OFC", "N", "F_c = Q u̇ − P, the generalized constraint force, in the order [u_I, u_D]"),
    ("OLAM", "M", "λ, the multipliers: F_c = Jᵀλ"),
    # the rank-robust solve (kernels with ROBUST; docs/closed-loops.md §7)
    ("OSV", "RB * 18", "the solve's settings and state (csrc/nmk.h: SV_*)"),
    ("OORD", "NR", "the current partition: J's columns in the order [u_I, u_D]"),
    ("OORDC", "NR", "the partition of the evaluation whose forces are wanted (its J2 copy's)"),
    ("OORD2", "NR", "a partition being tried; the pivot columns of Wehage & Haug's elimination"),
    ("OPOS", "NR", "each of J's columns' position in the order the paper's solve uses (OORD's inverse)"),
    ("OROWS", "MR", "row indices of that elimination"),
    ("ORN", "MR", "|J_i|∞, the row norms (equilibration)"),
    ("OCV", "MR", "c = −b + s, the right-hand side of J u̇ = c"),
    ("OSS", "MR", "s = [Γφ; Γ1ψ̇ + Γ2ψ], the Baumgarte terms"),
    ("OUS", "NR", "the Baumgarte terms' part of u̇ (J u̇_s = s, P = 0)"),
    ("OJE", "MR * NR", "the equilibrated J2 and its LU, or J for the elimination"),
    ("OLL", "NR * NR", "L, the Cholesky factor of Q (or of the projection's weight)"),
    ("OKK", "NR * MR", "K = L⁻¹Jᵀ and its Householder QR (R above the diagonal, the reflectors below)"),
    ("OAH", "NR", "â = L⁻¹P"),
    ("OEE", "MR", "e = c − Kᵀâ, equilibrated"),
    ("ONRM", "MR", "the column norms of K"),
    ("OPIV", "MR", "the QR's column order (the first rank ones kept)"),
    ("OBETA", "MR", "the reflectors' coefficients"),
    ("OYY", "MR", "y: R11ᵀ y = e"),
    ("OZZ", "NR", "z = Z_r y"),
    ("OQM", "NR * NR", "Q in the model's order (projections)"),
    ("ODX", "2 * NR", "an error estimate projected on the tangent space (adaptive steps)"),
    ("ODROP", "MR", "1.0 for each equation the last robust solve dropped"),
)

#: the post-step projections' scratch array (csrc/projection.c)
PROJECTION_SCRATCH: tuple[tuple[str, str, str], ...] = (
    ("PS_OQ", "N * N", "Q in the model's order, and its LU"),
    ("PS_OY", "N * M", "Y = W⁻¹Gᵀ"),
    ("PS_OZ", "N * M", "a second n×m block"),
    ("PS_OS", "M * M", "S = G W⁻¹ Gᵀ"),
    ("PS_OZR", "M", "z = S⁻¹ r"),
    ("PS_OD", "N", "δ = Y z"),
    ("PS_OG", "M * N + M + N", "G (m×n, model column order) and r (m) of the correction"),
)


def layout(table, dims: dict[str, int]) -> tuple[dict[str, int], int]:
    """(offset of each block, total size) of a work-array table for these dimensions."""
    offsets, pos = {}, 0
    for name, size, _ in table:
        offsets[name] = pos
        pos += block_size(size, dims)
    return offsets, pos


def block_size(expr: str, dims: dict[str, int]) -> int:
    """A size expression of the tables above (names of ``dims``, integers, + and *) evaluated."""

    def value(node: ast.AST) -> int:
        if isinstance(node, ast.Constant) and isinstance(node.value, int):
            return node.value
        if isinstance(node, ast.Name):
            return int(dims[node.id])
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Mult)):
            a, b = value(node.left), value(node.right)
            return a + b if isinstance(node.op, ast.Add) else a * b
        raise ValueError(f"not a size expression: {expr!r}")

    return value(ast.parse(expr, mode="eval").body)
