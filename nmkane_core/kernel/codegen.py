"""Kernel source generated from the symbolic derivation: one Python module per model, for numba.

For a model, :func:`generate_source` writes one module:

1. the model-specific part, generated here: dimensions, the permutation [u_I, u_D] → u, the
   offsets of the work arrays (:data:`~nmkane_core.kernel.interface.WORKSPACE`,
   :data:`~nmkane_core.kernel.interface.PROJECTION_SCRATCH`), the loop constants (imported
   from :mod:`nmkane_core.kernel.constants`), and straight-line functions after
   common-subexpression elimination — ``terms`` (J = [J1 J2], B1u + B2, φ, ψ̇, ψ, Q, P,
   C u + D), ``constraint_terms``, ``positions``, ``diagnostics`` (energy, constraint values)
   and ``outputs``;
2. the generic part, the source of :mod:`nmkane_core.kernel.source` (the numeric solve of
   T u̇ = V̂ without allocation and the tableau-driven integrator loops), with each loop's
   parameter list written from its argument record (:mod:`nmkane_core.kernel.interface`) and
   the calls marked ``# INLINE`` expanded (:mod:`nmkane_core.kernel.inline`).

Every function is ``@njit(cache=True)``; :mod:`nmkane_core.kernel.loader` writes the module to
a cache folder keyed by a hash of its text, so a second process loads the compiled machine
code instead of compiling again.  Parameters, Γ matrices, steps and horizons are runtime
arguments: nothing recompiles when a slider moves.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from . import constants, native
from .inline import inline_marked
from .interface import LOOPS, PROJECTION_SCRATCH, WORKSPACE, layout, parameter_list
from .printing import python_printer

__all__ = ["GENERIC_FILES", "generate_source"]

#: the generic compiled code appended to every generated kernel (not imported as modules)
GENERIC_FILES = (
    "source/loops.py",
    "source/paper.py",
    "source/state.py",
    "source/projection.py",
    "source/robust.py",
    "source/robust_linalg.py",
    "source/robust_projection.py",
)

#: numba's ``fastmath`` flags of every generated function: none.  With ``{'contract'}`` LLVM
#: fused multiplies and adds where the host CPU has FMA instructions, so one kernel rounded
#: differently on different machines, and expressions equal in exact arithmetic (the links of a
#: symmetric chain) rounded differently from each other: a round-off asymmetry that a singular
#: position amplifies (a closed-loop step-size test failed on one x86-64 machine, 1.2e-6 m/s off,
#: and passed on another, 4.1e-7; docs/closed-loops.md §7.4).  Without fast-math flags LLVM
#: neither contracts nor reassociates, whatever CPU it compiles for: results are the same bits on
#: every x86-64 machine (tests/systems/test_closed_loops_compiled.py compiles for a generic CPU
#: and compares), for ≈ 8 % more time per evaluation on the paper's small model
FASTMATH: frozenset[str] = frozenset()
#: expression trees larger than this (nodes, summed over one function) skip cse's pre-optimizations
#: (factoring, which costs time that grows fast with the size; the functions of most built-in
#: models are below it, the largest terms and those of large closed loops above)
CSE_BASIC_MAX_NODES = 3_000
#: a function writing more zeros than this into the work array writes them with one loop over each
#: block first (a large model's J, Q, ∂ψ/∂q and C are mostly zeros: thousands of statements less
#: for numba to compile), then only the nonzero entries
ZERO_FILL_MIN = 200
#: a model's ``terms`` with more statements than this is called by the right-hand side, not pasted
#: into it: numba then compiles it once (~10 s for a thousand statements) and every loop links that
#: compiled code (~1 s), where a pasted copy is compiled again in each loop that uses it; the call
#: costs nothing measurable against such a body, while small models keep the pasted body (a call
#: costs them ~20% of the loop's time)
INLINE_TERMS_MAX_STATEMENTS = 300


@dataclass
class Block:
    """One straight-line function after common-subexpression elimination, ready to print (as
    numba source here, as C by :mod:`nmkane_core.kernel.native`): the state and parameter
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


def _block(name: str, signature: str, block: Block, returns: str | None = None, inline: bool = False) -> str:
    """One straight-line numba function: unpack state and parameters, the CSE'd block."""
    printer = python_printer()
    flags = ', inline="always"' if inline else ""
    # error_model="numpy": x/0 gives ±inf or NaN, as √ of a negative number does, instead of raising
    # ZeroDivisionError from compiled code; the loops' finiteness checks then end the run with a status
    lines = [f'@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy"{flags})', f"def {name}({signature}):"]
    lines += [f"    x_{i} = x[{i}]" for i in block.x_used]
    lines += [f"    p_{i} = p[{i}]" for i in block.p_used]
    for lo, hi in block.zero_fill:
        lines.append(f"    for _k in range({lo}, {hi}):")
        lines.append("        w[_k] = 0.0")
    for sym, e in block.replacements:
        lines.append(f"    {sym} = {printer.doprint(e)}")
    for target, e, comment in block.outputs:
        lines.append(f"    {target} = {printer.doprint(e)}" + (f"  # {comment}" if comment else ""))
    if returns:
        lines.append(f"    return {returns}")
    if len(lines) == 2:
        lines.append("    pass")
    return "\n".join(lines) + "\n"


def needs_robust(derivation) -> bool:
    """Whether a model's kernel gets the rank-robust solve (``ROBUST``): it has constraints and
    either no declared partition, more equations than dependent speeds (redundant ones), or
    the declaration that its motion may pass singular positions.  Other kernels (the paper's
    systems) are generated and compiled without it: numba prunes every ``if ROBUST:``."""
    d = derivation
    md = d.model
    return bool(d.m) and (d.p == 0 or md.n - d.p != d.m or bool(getattr(md, "singular_positions", False)))


def kernel_dims(kt, robust: bool) -> dict[str, int]:
    """The dimensions the work-array tables and the generic source use: the model's (N, M, MNH,
    MH, NV, NO), PI = N − M the paper's solve's independent speeds, and NR, MR, RB — N, M and 1
    in kernels with the rank-robust solve, else 0."""
    d = dict(kt.dims)
    if robust:
        d["PI"] = max(d["N"] - d["M"], 0)
    d.update(NR=d["N"] if robust else 0, MR=d["M"] if robust else 0, RB=1 if robust else 0)
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
)


def generate_source(derivation, native_code: bool = True) -> str:
    """The whole kernel module for one model, as text.  A model whose ``terms`` are too large
    to paste into the right-hand side gets its model-specific functions as C
    (:mod:`nmkane_core.kernel.native`) when a C compiler is there and ``native_code``."""
    from ..symbolic.terms import kernel_terms

    kt = kernel_terms(derivation)
    robust = needs_robust(derivation)
    dims = kernel_dims(kt, robust)
    off, wsize = layout(WORKSPACE, dims)
    assignments = {
        "terms": _terms_assignments(kt, off),
        "constraint_terms": _constraint_assignments(kt, off),
        "positions": _position_assignments(kt, off),
        "diagnostics": [(f"viol[{i}]", e) for i, e in enumerate(kt.viol)] + [("_E", kt.energy)],
        "outputs": [(f"out[{i}]", e) for i, e in enumerate(kt.outputs)],
    }
    blocks = {name: _cse(kt, assignments[name]) for name, *_ in MODEL_FUNCTIONS}
    large = blocks["terms"].statements > INLINE_TERMS_MAX_STATEMENTS
    model_part = (native_code and large and _native_source(blocks)) or _numba_source(blocks)
    parts = [_head(kt, dims, derivation, off, wsize, robust), model_part, _projection_layout_source()]
    keep = {"terms"} if large else set()
    keep.add("_rhs_paper" if robust else "_rhs_robust")  # the branch numba prunes stays a call
    return inline_marked("\n\n".join(parts) + _generic_source(), keep_calls=keep)


def _numba_source(blocks: dict[str, Block]) -> str:
    """The model-specific functions as numba source."""
    return "\n\n".join(
        _block(name, ", ".join([*args, out]), blocks[name], returns=returns)
        for name, args, out, returns in MODEL_FUNCTIONS
    )


def _native_source(blocks: dict[str, Block]) -> str | None:
    """The model-specific functions as C (embedded in the module, compiled into a library beside
    it when the module is imported) and their numba wrappers; None without a C compiler or for
    an expression C cannot write."""
    if native.compiler() is None:
        return None
    try:
        functions = [
            native.c_function(name, args, out, blocks[name], returns) for name, args, out, returns in MODEL_FUNCTIONS
        ]
    except ValueError:
        return None
    source, tag = native.c_module(functions)
    head = [
        "# the model-specific functions in C (kernel.native): compiled beside this module, then called",
        "from numba import types",
        "",
        "from nmkane_core.kernel import native as _native",
        "",
        f"NATIVE_TAG = {tag!r}",
        f"NATIVE_SOURCE = {source!r}",
        "_native.load(__file__, NATIVE_TAG, NATIVE_SOURCE)",
        "_PD = types.CPointer(types.float64)",
    ]
    wrappers = [
        native.numba_wrapper(name, args, out, tag, returns is not None) for name, args, out, returns in MODEL_FUNCTIONS
    ]
    return "\n".join(head) + "\n\n\n" + "\n\n".join(wrappers)


def _head(kt, d: dict[str, int], derivation, off: dict[str, int], wsize: int, robust: bool) -> str:
    """Imports, dimensions, constants and work-array offsets of the generated module."""
    import sympy as sp

    from ..symbolic import robust as rb

    model_name = derivation.model.name
    head = [
        f"# Generated by nmkane_core.kernel.codegen for model {model_name!r}. Do not edit.",
        f"# state: {', '.join(map(str, kt.args_x))}; params: {', '.join(map(str, kt.args_p))}",
        f"# violations: {', '.join(kt.viol_names)}; outputs: {', '.join(kt.output_names)}",
        "import math",
        "import numpy as np",
        "from numba import njit",
        "",
        f"from nmkane_core.kernel.constants import {', '.join(constants.NAMES)}",
        "",
        "# no fast-math flags: plain IEEE arithmetic, the same on every x86-64 CPU (see FASTMATH)",
        f"FM = {set(FASTMATH)!r}",
    ]
    head += [f"{k} = {v}" for k, v in d.items()]
    p = derivation.p
    head += [
        f"ROBUST = {robust}  # the rank-robust constraint solve (codegen.needs_robust; source/robust.py)",
        f"C_IS_I = {sp.eye(d['N']) == derivation.C}  # q̇ = u",
        f"RANK_TOL_DEFAULT = {rb.RANK_TOL!r}",
        f"CONSISTENCY_TOL_DEFAULT = {rb.CONSISTENCY_TOL!r}",
        f"RCOND_ROBUST_DEFAULT = {rb.RCOND_ROBUST!r}",
        f"BAUMGARTE_FADE = {rb.BAUMGARTE_FADE!r}  # the Baumgarte terms of vanishing rows fade (symbolic.robust)",
        f"MAX_RANK_DEFAULT = {d['N'] - p if p else min(d['N'], d['M'])}  # n − p (declared), else at most min(n, m)",
    ]
    head.append(f"PERM = np.array({kt.perm!r}, dtype=np.int64)")
    head += _sparsity_source("Q", kt.Q, "Q's structural nonzeros by row ([u_I, u_D] order; CSR)")
    head += _sparsity_source("J", kt.J, "J's structural nonzeros by row (CSR)")
    head.append(
        f"ROWDEG = np.array({(kt.row_degree or [1])!r}, dtype=np.int64)  # degree in u of each row of J"
        "  (0: not a polynomial)"
    )
    head.append(f"SCALE_ROWS = {any(k > 1 for k in kt.row_degree)}  # some rows polynomial of degree > 1 in u")
    head.append(f"NORM_ROWS = {any(k == 0 for k in kt.row_degree)}  # some rows not polynomial in u")
    head.append("# offsets into the flat work array (kernel.interface.WORKSPACE)")
    head += [f"{name} = {pos}" for name, pos in off.items()]
    head.append(f"WSIZE = {wsize}")
    ps_off, ps_size = layout(PROJECTION_SCRATCH, d)
    head.append("# offsets into the projections' scratch array (kernel.interface.PROJECTION_SCRATCH)")
    head += [f"{name} = {pos}" for name, pos in ps_off.items()]
    head.append(f"PS_SIZE = {ps_size}")
    return "\n".join(head) + "\n"


def _sparsity_source(name: str, matrix, what: str) -> list[str]:
    """``{name}PTR``, ``{name}IDX``: where a matrix can be nonzero, row by row (compressed
    sparse rows): the entries that are not identically zero.  The rank-robust solve's products
    with Q and J run over these only — a long chain's Q and J have a few entries a row, and
    the dense loops over them were most of a right-hand side at 81 coordinates."""
    ptr, idx = [0], []
    for i in range(matrix.rows):
        idx += [j for j in range(matrix.cols) if matrix[i, j] != 0]
        ptr.append(len(idx))
    return [
        f"# {what}",
        f"{name}PTR = np.array({ptr!r}, dtype=np.int64)",
        f"{name}IDX = np.array({(idx or [0])!r}, dtype=np.int64)",
    ]


def _projection_layout_source() -> str:
    """``projection_layout(N, M)``: the projection scratch offsets for runtime dimensions."""
    lines = [
        '@njit(cache=True, nogil=True, error_model="numpy")',
        "def projection_layout(N, M):",
        '    """Offsets of kernel.interface.PROJECTION_SCRATCH (and its size) for runtime N, M."""',
        "    pos = N - N",
    ]
    names = []
    for name, size, _ in PROJECTION_SCRATCH:
        lines.append(f"    {name.lower()} = pos")
        lines.append(f"    pos += {size}")
        names.append(name.lower())
    lines.append(f"    return {', '.join(names)}, pos")
    return "\n".join(lines) + "\n"


def _generic_source() -> str:
    """The generic numba source, each loop's ``*Args`` replaced by its record's fields."""
    text = "".join(
        f"\n\n# ---- generic part: nmkane_core/kernel/{name} ----\n" + (Path(__file__).parent / name).read_text()
        for name in GENERIC_FILES
    )
    for loop, args in LOOPS.items():
        marker = re.compile(rf"^def {loop}\(\*{args.__name__}\):", re.MULTILINE)
        text, found = marker.subn(f"def {loop}({parameter_list(args)}):", text)
        if found != 1:
            raise RuntimeError(f"the loop source must define def {loop}(*{args.__name__}): once")
    return text


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
