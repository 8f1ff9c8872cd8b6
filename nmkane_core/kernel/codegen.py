"""A model's kernel description, generated from the symbolic derivation.

For a model, :func:`generate_source` writes one JSON text (the kernel cache keeps it):

1. the sizes and constants the compiled core reads at run time (:mod:`nmkane_core.kernel.core`'s
   model record): dimensions, the offsets of the work arrays
   (:data:`~nmkane_core.kernel.interface.WORKSPACE`,
   :data:`~nmkane_core.kernel.interface.PROJECTION_SCRATCH`), the permutation [u_I, u_D] → u, the
   sparsity of Q and J, the rank-robust solve's switch and defaults;
2. the model's straight-line functions as C, after common-subexpression elimination — ``terms``
   (J = [J1 J2], B1u + B2, φ, ψ̇, ψ, Q, P, C u + D), ``constraint_terms``, ``positions``,
   ``diagnostics`` (energy, constraint values), ``outputs`` and ``kinematics`` (C, where it
   varies: the kinematics' estimate) — which
   :mod:`nmkane_core.kernel.native` compiles into the model's library.

No loop is generated per model: the loops, solves and projections are compiled once
(:mod:`nmkane_core.kernel.core`).  Parameters, Γ matrices, steps and horizons are run-time
arguments: nothing recompiles when a slider moves.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..errors import InputError
from . import native
from .cmodel import description_json
from .interface import PROJECTION_SCRATCH, WORKSPACE, layout

__all__ = ["generate_source"]

#: expression trees larger than this (nodes, summed over one function) skip cse's pre-optimizations
#: (factoring, which costs time that grows fast with the size; the functions of most built-in
#: models are below it, the largest terms and those of large closed loops above)
CSE_BASIC_MAX_NODES = 3_000
#: a function writing more zeros than this into the work array writes them with one loop over each
#: block first (a large model's J, Q, ∂ψ/∂q and C are mostly zeros: thousands of statements less
#: for the compiler), then only the nonzero entries
ZERO_FILL_MIN = 200


@dataclass
class Block:
    """One straight-line function after common-subexpression elimination, ready to print (as
    as C by :mod:`nmkane_core.kernel.native`): the state and parameter
    entries it reads, the ranges of ``w`` it zeroes first, the subexpressions ``c_k`` and the
    assignments ``(target, expression, comment)``."""

    x_used: list[int]
    p_used: list[int]
    zero_fill: list[tuple[int, int]]
    replacements: list[tuple]
    outputs: list[tuple]

    @property
    def statements(self) -> int:
        return (
            len(self.x_used) + len(self.p_used) + 2 * len(self.zero_fill) + len(self.replacements) + len(self.outputs)
        )


def _cse(kt, assignments: list[tuple]) -> Block:
    """The :class:`Block` of ``assignments`` (``(target, expression[, comment])``): the model's
    symbols renamed ``x_i``, ``p_i``, ``t``, zeros written by loops (:func:`_zero_fill`), CSE."""
    import sympy as sp

    xs = [sp.Symbol(f"x_{i}", real=True) for i in range(len(kt.args_x))]
    ps = [sp.Symbol(f"p_{i}", real=True) for i in range(len(kt.args_p))]
    sub = dict(zip(kt.args_x, xs, strict=True))
    sub.update(zip(kt.args_p, ps, strict=True))
    sub[kt.args_t] = sp.Symbol("t", real=True)
    assignments, zero_fill = _zero_fill(assignments)
    exprs = [sp.sympify(a[1]).xreplace(sub) for a in assignments]
    # cse's "basic" pre-optimizations (factoring) save a few percent of operations but cost
    # time that grows fast with the size: the terms of a model with 8 coordinates and 5
    # constraints take 8 s with them, 0.6 s without
    size = sum(1 for e in exprs for _ in sp.preorder_traversal(e))
    repl, reduced = sp.cse(
        exprs, symbols=sp.numbered_symbols("c_"), optimizations="basic" if size <= CSE_BASIC_MAX_NODES else None
    )
    used = set()
    for e in exprs:
        used |= {s.name for s in sp.sympify(e).free_symbols}
    return Block(
        x_used=[i for i, s in enumerate(xs) if s.name in used],
        p_used=[i for i, s in enumerate(ps) if s.name in used],
        zero_fill=zero_fill,
        replacements=list(repl),
        outputs=[(a[0], e, a[2] if len(a) > 2 else "") for a, e in zip(assignments, reduced, strict=True)],
    )


def needs_robust(derivation) -> bool:
    """Whether a model's kernel gets the rank-robust solve (``ROBUST``): every model with
    constraints.  A declared partition is the preferred one (``solve="auto"`` keeps it where its
    J2 is well-conditioned, and re-partitions or uses the robust solve elsewhere); ``"paper"``
    with a declared, non-redundant partition runs the paper's solve alone (``DECLARED``)."""
    return bool(derivation.m)


def declared_partition(derivation) -> bool:
    """Whether J's columns are a declared, non-redundant partition [u_I, u_D] (``DECLARED``): the
    paper's solve of such a kernel is the paper's own path (its bits, its condition estimate)."""
    d = derivation
    return bool(d.m) and d.p > 0 and d.model.n - d.p == d.m


def kinematic_block(derivation) -> tuple[list[int], list[int]]:
    """The rows and columns of the kinematics' C (q̇ = C u + D) whose estimate the kernel computes
    (csrc/kinematics.c): none where C is constant — the identity of most mechanisms, whose runs
    compute nothing more — else the rows with an entry that depends on the coordinates, the speeds
    or the time (such a C may degenerate: Euler angles at gimbal lock) and the columns of their
    nonzero entries.  The other rows must then each hold one constant entry, in a column of its
    own (a body's position q̇ = v beside its angles): their normalized block is a signed
    permutation, of estimate 1, and the block's estimate is C's.  Otherwise every row and column."""
    md = derivation.model
    C = derivation.C
    moving = {*md.q, *md.u, md.t}
    rows = [i for i in range(C.rows) if any(C[i, j].free_symbols & moving for j in range(C.cols))]
    if not rows:
        return [], []
    cols = sorted({j for i in rows for j in range(C.cols) if C[i, j] != 0})
    rest = [[j for j in range(C.cols) if C[i, j] != 0] for i in range(C.rows) if i not in rows]
    single = [r[0] for r in rest if len(r) == 1]
    if (
        len(cols) == len(rows)
        and len(single) == len(rest)
        and len(set(single)) == len(single)
        and not set(single) & set(cols)
    ):
        return rows, cols
    return list(range(C.rows)), list(range(C.cols))


def kernel_dims(kt, robust: bool) -> dict[str, int]:
    """The dimensions the work-array tables and the generic source use: the model's (N, M, MNH,
    MH, NV, NO), PI = N − M the paper's solve's independent speeds, NR, MR, RB — N, M and 1
    in kernels with the rank-robust solve, else 0 — and KN, the size of the kinematics' block whose
    estimate is computed (0 where C is constant: :func:`kinematic_block`)."""
    d = dict(kt.dims)
    if robust:
        d["PI"] = max(d["N"] - d["M"], 0)
    d.update(NR=d["N"] if robust else 0, MR=d["M"] if robust else 0, RB=1 if robust else 0)
    d["KN"] = len(kinematic_block(kt.derivation)[0])
    return d


def _zero_fill(assignments: list[tuple]) -> tuple[list[tuple], list[tuple[int, int]]]:
    """(the assignments to make one by one, ranges of the work array to fill with zeros first):
    with more than :data:`ZERO_FILL_MIN` zeros written into ``w``, every contiguous range of
    ``w`` entries the function writes is zeroed by a loop and only the nonzero ones are assigned."""
    import sympy as sp

    where = re.compile(r"^w\[(\d+)\]$")
    zeros = [a for a in assignments if where.match(a[0]) and sp.sympify(a[1]) == 0]
    if len(zeros) <= ZERO_FILL_MIN:
        return assignments, []
    index = sorted(int(hit.group(1)) for a in assignments if (hit := where.match(a[0])) is not None)
    ranges: list[list[int]] = []
    for k in index:
        if ranges and k == ranges[-1][1]:
            ranges[-1][1] = k + 1
        else:
            ranges.append([k, k + 1])
    kept = [a for a in assignments if not (where.match(a[0]) and sp.sympify(a[1]) == 0)]
    return kept, [(a, b) for a, b in ranges]


#: the model-specific functions: (name, arguments, output array, returned name)
MODEL_FUNCTIONS = (
    ("terms", ("t", "x", "p"), "w", None),
    ("constraint_terms", ("t", "x", "p"), "w", None),
    ("positions", ("t", "x", "p"), "w", None),
    ("diagnostics", ("t", "x", "p"), "viol", "_E"),
    ("outputs", ("t", "x", "p"), "out", None),
    ("kinematics", ("t", "x", "p"), "w", None),
)


def generate_source(derivation) -> str:
    """The kernel description of one model, as text (:func:`~.cmodel.description_json`)."""
    from ..symbolic.terms import kernel_terms

    kt = kernel_terms(derivation)
    robust = needs_robust(derivation)
    dims = kernel_dims(kt, robust)
    off = layout(WORKSPACE, dims)[0]
    assignments = {
        "terms": _terms_assignments(kt, off),
        "constraint_terms": _constraint_assignments(kt, off),
        "positions": _position_assignments(kt, off),
        "diagnostics": [(f"viol[{i}]", e) for i, e in enumerate(kt.viol)] + [("_E", kt.energy)],
        "outputs": [(f"out[{i}]", e) for i, e in enumerate(kt.outputs)],
        "kinematics": _kinematics_assignments(kt, off),
    }
    functions = []
    for name, args, out, returns in MODEL_FUNCTIONS:
        try:
            functions.append(native.c_function(name, args, out, _cse(kt, assignments[name]), returns))
        except ValueError as e:
            raise InputError(
                "model", derivation.model.name, "expressions of functions C's math library has", reason=str(e)
            ) from None
    source, tag = native.c_module(functions)
    ints, floats, arrays = _record_fields(kt, dims, derivation, robust)
    description = {
        "generator": "nmkane_core.kernel.codegen",
        "model": derivation.model.name,
        "state": [str(s) for s in kt.args_x],
        "params": [str(s) for s in kt.args_p],
        "violations": list(kt.viol_names),
        "outputs": list(kt.output_names),
        "np": len(kt.args_p),
        "ints": ints,
        "floats": floats,
        "arrays": arrays,
        "tag": tag,
        "c_source": source,
    }
    return description_json(description)


def _record_fields(kt, dims: dict[str, int], derivation, robust: bool) -> tuple[dict, dict, dict]:
    """The model record's integers (sizes, switches, offsets), floats (the robust solve's
    defaults) and int64 arrays (permutation, sparsity, row degrees) (kernel.core's ``nmk_model``)."""
    import sympy as sp

    from ..symbolic import robust as rb

    off, wsize = layout(WORKSPACE, dims)
    ps_off, ps_size = layout(PROJECTION_SCRATCH, dims)
    p = derivation.p
    ints = {
        **dims,
        "ROBUST": int(robust),
        "DECLARED": int(declared_partition(derivation)),
        "C_IS_I": int(sp.eye(dims["N"]) == derivation.C),
        "SCALE_ROWS": int(any(k > 1 for k in kt.row_degree)),
        "NORM_ROWS": int(any(k == 0 for k in kt.row_degree)),
        "MAX_RANK_DEFAULT": dims["N"] - p if p else min(dims["N"], dims["M"]),  # n − p declared, else ≤ min(n, m)
        **off,
        "WSIZE": wsize,
        **ps_off,
        "PS_SIZE": ps_size,
    }
    floats = {
        "RANK_TOL_DEFAULT": rb.RANK_TOL,
        "CONSISTENCY_TOL_DEFAULT": rb.CONSISTENCY_TOL,
        "RCOND_ROBUST_DEFAULT": rb.RCOND_ROBUST,
        "BAUMGARTE_FADE": rb.BAUMGARTE_FADE,
    }
    qptr, qidx = _sparsity(kt.Q)
    jptr, jidx = _sparsity(kt.J)
    arrays = {
        "PERM": list(kt.perm),
        "QPTR": qptr,
        "QIDX": qidx,
        "JPTR": jptr,
        "JIDX": jidx,
        "ROWDEG": list(kt.row_degree or [1]),  # degree in u of each row of J (0: not a polynomial)
    }
    return ints, floats, arrays


def _sparsity(matrix) -> tuple[list[int], list[int]]:
    """Where a matrix can be nonzero, row by row (compressed sparse rows: pointers, column
    indices): the entries that are not identically zero.  The rank-robust solve's products with
    Q and J run over these only — a long chain's Q and J have a few entries a row."""
    ptr, idx = [0], []
    for i in range(matrix.rows):
        idx += [j for j in range(matrix.cols) if matrix[i, j] != 0]
        ptr.append(len(idx))
    return ptr, idx or [0]


def _terms_assignments(kt, off: dict[str, int]) -> list[tuple]:
    """What ``terms`` writes into the work array: J, b, φ, ψ̇, ψ, Q, P, q̇."""
    d = kt.dims
    N, M = d["N"], d["M"]
    assign = []
    for i in range(M):
        for j in range(N):
            assign.append((f"w[{off['OJ'] + i * N + j}]", kt.J[i, j], f"J[{i},{j}]"))
        assign.append((f"w[{off['OB'] + i}]", kt.b[i], f"b[{i}]"))
    assign += [(f"w[{off['OPHIN'] + i}]", e, f"phi[{i}]") for i, e in enumerate(kt.phin)]
    assign += [(f"w[{off['OPSID'] + i}]", e, f"psidot[{i}]") for i, e in enumerate(kt.psid)]
    assign += [(f"w[{off['OPSI'] + i}]", e, f"psi[{i}]") for i, e in enumerate(kt.psi)]
    for i in range(N):
        for j in range(N):
            assign.append((f"w[{off['OQ'] + i * N + j}]", kt.Q[i, j], f"Q[{i},{j}]"))
        assign.append((f"w[{off['OP'] + i}]", kt.P[i], f"P[{i}]"))
        assign.append((f"w[{off['OQD'] + i}]", kt.qdot[i], f"qdot[{i}]"))
    return assign


def _constraint_assignments(kt, off: dict[str, int]) -> list[tuple]:
    """The velocity-level constraint quantities alone (J, φ, ψ̇), for completing and checking
    initial states (``state_terms``): without Q and P, which for a large model are most of ``terms``."""
    return [a for a in _terms_assignments(kt, off) if a[2].startswith(("J[", "phi[", "psidot["))]


def _kinematics_assignments(kt, off: dict[str, int]) -> list[tuple]:
    """What ``kinematics`` writes: the block of C whose estimate the kernel computes
    (:func:`kinematic_block`, KN × KN) into w[OCK], row by row; nothing where C is constant."""
    rows, cols = kinematic_block(kt.derivation)
    C, k = kt.derivation.C, len(rows)
    return [
        (f"w[{off['OCK'] + a * k + b}]", C[i, j], f"C[{i},{j}]") for a, i in enumerate(rows) for b, j in enumerate(cols)
    ]


def _position_assignments(kt, off: dict[str, int]) -> list[tuple]:
    """What the position projection needs: ψ, ∂ψ/∂q and C."""
    import sympy as sp

    d = kt.dims
    N, MH = d["N"], d["MH"]
    kin = [(f"w[{off['OPSI'] + i}]", e, f"psi[{i}]") for i, e in enumerate(kt.psi)]
    psi_q = kt.psi.jacobian(sp.Matrix(kt.args_x[:N])) if MH else sp.zeros(0, N)
    for i in range(MH):
        for j in range(N):
            kin.append((f"w[{off['OPSQ'] + i * N + j}]", psi_q[i, j], f"psi_q[{i},{j}]"))
    C = kt.derivation.C
    for i in range(N):
        for j in range(N):
            kin.append((f"w[{off['OC'] + i * N + j}]", C[i, j], f"C[{i},{j}]"))
    return kin
