"""Compiled kernels generated from the symbolic derivation (numba), cached on disk.

For a model, :func:`compiled_kernel` writes one Python module:

1. the model-specific part, generated here: dimensions, the permutation [u_I, u_D] → u,
   and straight-line functions after common-subexpression elimination —
   ``terms`` (J = [J1 J2], B1u + B2, φ, ψ̇, ψ, Q, P, C u + D), ``diagnostics`` (energy,
   constraint values) and ``outputs``;
2. the generic part, the source of :mod:`nmkane_core.kernel.source.loops` (the numeric solve of
   T u̇ = V̂ without allocation and the tableau-driven integrator loops).

Every function is ``@njit(cache=True)``: the module lives in a cache directory keyed by a
hash of its source, so a second process imports it and loads the compiled machine code
instead of compiling again.  Parameters, Γ matrices, steps and horizons are runtime
arguments: nothing recompiles when a slider moves.
"""

from __future__ import annotations

import ast
import contextlib
import copy
import hashlib
import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path

from . import precompile
from .cache import import_kernel, kernel_dir, write_kernel
from .info import ModelInfo

__all__ = ["cache_dir", "generate_source", "compiled_kernel", "kernel", "fingerprint"]

#: the generic compiled code appended to every generated kernel (not imported as modules)
GENERIC_FILES = ("source/loops.py", "source/state.py", "source/projection.py")

_LOCK = threading.Lock()

#: expression trees larger than this (nodes, summed over one function) skip cse's pre-optimizations
CSE_BASIC_MAX_NODES = 20_000
#: a model's ``terms`` with more statements than this is called by the right-hand side, not pasted
#: into it: numba then compiles it once (~10 s for a thousand statements) and every loop links that
#: compiled code (~1 s), where a pasted copy is compiled again in each loop that uses it; the call
#: costs nothing measurable against such a body, while small models keep the pasted body (a call
#: costs them ~20% of the loop's time)
INLINE_TERMS_MAX_STATEMENTS = 300
_LOADED: dict[str, object] = {}


def cache_dir() -> Path:
    """Where generated kernels live (see :mod:`nmkane_core.kernel.cache`)."""
    return kernel_dir()


def _printer():
    import sympy as sp
    from sympy.printing.pycode import PythonCodePrinter

    class _Printer(PythonCodePrinter):
        def _print_Pow(self, expr, rational=False):
            # integer powers as products/divisions: exact and fast in compiled code
            base, exp = expr.as_base_exp()
            if exp.is_Integer and 1 < abs(int(exp)) <= 4:
                b = self.parenthesize(base, 100)
                prod = "*".join([b] * abs(int(exp)))
                return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
            if exp == sp.S.Half:
                return f"math.sqrt({self._print(base)})"
            return super()._print_Pow(expr, rational=rational)

    return _Printer({"fully_qualified_modules": True, "standard": "python3"})


def _block(
    name: str, signature: str, kt, assignments: list[tuple], returns: str | None = None, inline: bool = False
) -> str:
    """One straight-line function: unpack state and parameters, CSE, assign outputs."""
    import sympy as sp

    printer = _printer()
    xs = [sp.Symbol(f"x_{i}", real=True) for i in range(len(kt.args_x))]
    ps = [sp.Symbol(f"p_{i}", real=True) for i in range(len(kt.args_p))]
    tt = sp.Symbol("t", real=True)
    sub = dict(zip(kt.args_x, xs, strict=True))
    sub.update(zip(kt.args_p, ps, strict=True))
    sub[kt.args_t] = tt
    exprs = [sp.sympify(a[1]).xreplace(sub) for a in assignments]
    # cse's "basic" pre-optimizations (factoring) save a few percent of operations but cost
    # time that grows fast with the size: a bicycle's terms take 8 s with them, 0.6 s without
    size = sum(1 for e in exprs for _ in sp.preorder_traversal(e))
    repl, reduced = sp.cse(
        exprs, symbols=sp.numbered_symbols("c_"), optimizations="basic" if size <= CSE_BASIC_MAX_NODES else None
    )
    used = set()
    for e in exprs:
        used |= {s.name for s in sp.sympify(e).free_symbols}
    flags = ', inline="always"' if inline else ""
    # error_model="numpy": x/0 gives ±inf or NaN, as √ of a negative number does, instead of raising
    # ZeroDivisionError from compiled code; the loops' finiteness checks then end the run with a status
    lines = [f'@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy"{flags})', f"def {name}({signature}):"]
    for i, s in enumerate(xs):
        if s.name in used:
            lines.append(f"    {s.name} = x[{i}]")
    for i, s in enumerate(ps):
        if s.name in used:
            lines.append(f"    {s.name} = p[{i}]")
    for sym, e in repl:
        lines.append(f"    {sym} = {printer.doprint(e)}")
    for a, e in zip(assignments, reduced, strict=True):
        comment = f"  # {a[2]}" if len(a) > 2 else ""
        lines.append(f"    {a[0]} = {printer.doprint(e)}{comment}")
    if returns:
        lines.append(f"    return {returns}")
    if len(lines) == 2:
        lines.append("    pass")
    return "\n".join(lines) + "\n"


def generate_source(derivation) -> str:
    """The whole kernel module for one model, as text."""
    import sympy as sp

    from ..symbolic.terms import kernel_terms

    kt = kernel_terms(derivation)
    d = kt.dims
    N, M = d["N"], d["M"]
    head = [
        f"# Generated by nmkane_core.kernel.codegen for model {derivation.model.name!r}. Do not edit.",
        f"# state: {', '.join(map(str, kt.args_x))}; params: {', '.join(map(str, kt.args_p))}",
        f"# violations: {', '.join(kt.viol_names)}; outputs: {', '.join(kt.output_names)}",
        "import math",
        "import numpy as np",
        "from numba import njit",
        "",
        "# IEEE-safe fast-math subset: contraction (FMA), reassociation, reciprocals; NaN/Inf",
        "# semantics are kept so that divergence is still detected",
        "FM = {'contract'}",
    ]
    head += [f"{k} = {v}" for k, v in d.items()]
    head.append(f"PERM = np.array({kt.perm!r}, dtype=np.int64)")
    head.append(
        f"ROWDEG = np.array({(kt.row_degree or [1])!r}, dtype=np.int64)  # degree in u of each row of J"
        "  (0: not a polynomial)"
    )
    head.append(f"SCALE_ROWS = {any(k > 1 for k in kt.row_degree)}  # some rows polynomial of degree > 1 in u")
    head.append(f"NORM_ROWS = {any(k == 0 for k in kt.row_degree)}  # some rows not polynomial in u")
    # offsets into the flat work array (see make_workspace in the generic part)
    sizes = [
        ("OJ", M * N),
        ("OB", M),
        ("OPHIN", d["MNH"]),
        ("OPSID", d["MH"]),
        ("OPSI", d["MH"]),
        ("OQ", N * N),
        ("OP", N),
        ("OQD", N),
        ("OR", M * (d["PI"] + 1)),
        ("OW", N * d["PI"]),
        ("OMR", d["PI"] ** 2),
        ("OY", N),
        ("OUI", d["PI"]),
        ("ORC", 2),
        ("OPSQ", d["MH"] * N),
        ("OC", N * N),
    ]
    off = {}
    pos = 0
    for name, size in sizes:
        off[name] = pos
        head.append(f"{name} = {pos}")
        pos += size
    head.append(f"WSIZE = {pos}")
    head.append("")
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
    # the velocity-level constraint quantities alone (J, φ, ψ̇), for completing and checking
    # initial states (state_terms): without Q and P, which for a large model are most of ``terms``
    cons = [a for a in assign if a[2].startswith(("J[", "phi[", "psidot["))]
    kin = [(f"w[{off['OPSI'] + i}]", e, f"psi[{i}]") for i, e in enumerate(kt.psi)]
    psi_q = kt.psi.jacobian(sp.Matrix(kt.args_x[:N])) if d["MH"] else sp.zeros(0, N)
    for i in range(d["MH"]):
        for j in range(N):
            kin.append((f"w[{off['OPSQ'] + i * N + j}]", psi_q[i, j], f"psi_q[{i},{j}]"))
    C = kt.derivation.C
    for i in range(N):
        for j in range(N):
            kin.append((f"w[{off['OC'] + i * N + j}]", C[i, j], f"C[{i},{j}]"))
    parts = [
        "\n".join(head),
        _block("terms", "t, x, p, w", kt, assign),
        _block("constraint_terms", "t, x, p, w", kt, cons),
        _block("positions", "t, x, p, w", kt, kin),
        _block(
            "diagnostics",
            "t, x, p, viol",
            kt,
            [(f"viol[{i}]", e) for i, e in enumerate(kt.viol)] + [("_E", kt.energy)],
            returns="_E",
        ),
        _block("outputs", "t, x, p, out", kt, [(f"out[{i}]", e) for i, e in enumerate(kt.outputs)]),
    ]
    generic = "".join(
        f"\n\n# ---- generic part: nmkane_core/{name} ----\n" + (Path(__file__).parent / name).read_text()
        for name in GENERIC_FILES
    )
    large = parts[1].count("\n") > INLINE_TERMS_MAX_STATEMENTS
    return inline_marked("\n\n".join(parts) + generic, keep_calls={"terms"} if large else ())


class _Rename(ast.NodeTransformer):
    """Rename variables (``str`` values) or substitute expressions (AST values)."""

    def __init__(self, mapping: dict):
        self.mapping = mapping

    def visit_Name(self, node):
        new = self.mapping.get(node.id)
        if new is None:
            return node
        if isinstance(new, str):
            return ast.copy_location(ast.Name(id=new, ctx=node.ctx), node)
        return ast.copy_location(copy.deepcopy(new), node)


def _inline_body(fn: ast.FunctionDef, args: list, target, tag: str) -> list:
    """The statements of ``fn`` for one call: parameters bound to ``args``, locals renamed
    apart with ``tag``, a final ``return e`` turned into ``target = e`` (dropped if no target)."""
    body = list(fn.body)
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        body = body[1:]  # the docstring
    returns = [n for st in body for n in ast.walk(st) if isinstance(n, ast.Return)]
    if returns and (len(returns) > 1 or body[-1] is not returns[0]):
        raise RuntimeError(f"{fn.name}: only a function whose one return ends it can be inlined")
    params = [a.arg for a in fn.args.args]
    if len(args) != len(params):
        raise RuntimeError(f"{fn.name}: called with {len(args)} arguments, takes {len(params)}")
    stores = {n.id for st in body for n in ast.walk(st) if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
    mapping, out = {}, []
    for name, arg in zip(params, args, strict=True):
        if name not in stores and isinstance(arg, (ast.Name, ast.Constant)):
            mapping[name] = arg.id if isinstance(arg, ast.Name) else arg  # substitute
        else:
            mapping[name] = tag + name  # bind once
            out.append(ast.Assign(targets=[ast.Name(id=tag + name, ctx=ast.Store())], value=arg))
    for name in stores - set(params):
        mapping[name] = tag + name
    out += [_Rename(mapping).visit(copy.deepcopy(st)) for st in body]
    if returns:
        value = out.pop().value
        if target is not None:
            out.append(ast.Assign(targets=[target], value=value))
    return out


def inline_marked(source: str, keep_calls=()) -> str:
    """Inline at source level every call marked ``# INLINE`` in the module ``source``.

    A marked statement is ``f(args)  # INLINE`` or ``target = f(args)  # INLINE`` with ``f``
    a function of the module whose only ``return`` (if any) ends it.  The call becomes
    ``f``'s body, parameters bound and locals renamed apart; marked calls inside ``f`` are
    expanded first.  numba's ``inline="always"`` does the same on its IR but deep-copies it
    for every call site (seconds of compilation for the right-hand side), and a plain call
    costs ~20% of the loop's time and keeps LLVM from forwarding the stores into the work
    array to their loads.  Functions without marked calls keep their text and comments.
    Calls of the functions named in ``keep_calls`` stay calls even when marked.
    """
    lines = source.splitlines()
    tree = ast.parse(source)
    funcs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
    expanded: dict = {}
    changed: dict[str, bool] = {}
    count = [0]

    def expand(fn: ast.FunctionDef) -> ast.FunctionDef:
        if fn.name not in expanded:

            class Expander(ast.NodeTransformer):
                def _inline(self, st, call, target):
                    if not (
                        "# INLINE" in lines[st.lineno - 1]
                        and isinstance(call, ast.Call)
                        and isinstance(call.func, ast.Name)
                        and call.func.id in funcs
                        and call.func.id not in keep_calls
                    ):
                        return st
                    count[0] += 1
                    callee = expand(funcs[call.func.id])
                    return _inline_body(callee, call.args, target, f"_{callee.name}{count[0]}_")

                def visit_Expr(self, st):
                    return self._inline(st, st.value, None)

                def visit_Assign(self, st):
                    return self._inline(st, st.value, st.targets[0]) if len(st.targets) == 1 else st

            new = Expander().visit(copy.deepcopy(fn))  # line numbers kept: markers
            changed[fn.name] = ast.dump(new) != ast.dump(fn)
            expanded[fn.name] = new
        return expanded[fn.name]

    out, pos = [], 0
    for fn in funcs.values():
        new = expand(fn)
        if not changed[fn.name]:
            continue
        first = min([fn.lineno] + [d.lineno for d in fn.decorator_list])
        out += lines[pos : first - 1]
        out.append(ast.unparse(ast.fix_missing_locations(new)))
        pos = fn.end_lineno or fn.lineno
    return "\n".join(out + lines[pos:]) + "\n"


def _source_key(source: str) -> str:
    import numba

    h = hashlib.sha256(source.encode())
    h.update(numba.__version__.encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:20]


def _import(folder: Path, key: str, source: str | None):
    """Import kernel ``key`` from ``folder``, writing ``source`` there first when given; a
    newly written kernel starts compiling its loop in a second process at once."""
    if source is not None and write_kernel(folder, key, source):
        precompile.start(folder, key)
    return import_kernel(folder, key)


def compiled_kernel(derivation, source: str | None = None):
    """Import (generating if needed) the compiled kernel module of a derivation."""
    if source is None:
        source = generate_source(derivation)
    key = _source_key(source)
    with _LOCK:
        if key not in _LOADED:
            _LOADED[key] = _import(cache_dir() / key, key, source)
        return _LOADED[key]


_CORE_FILES = (
    "../symbolic/model.py",
    "../symbolic/derivation.py",
    "../symbolic/terms.py",
    "codegen.py",
    *GENERIC_FILES,
    "info.py",
)


def fingerprint(system_name: str, variant: str, source_files, extra: str = "") -> str | None:
    """A key for a model's kernel that needs no sympy: the text of every file that defines
    the model, of the generator's files, the versions of the tools that generate it, and
    ``extra`` (which function of those files builds the model)."""
    if not source_files:
        return None
    h = hashlib.sha256(_tools_key(system_name, variant).encode())
    h.update(extra.encode())
    for f in sorted(set(map(str, source_files))):
        h.update(Path(f).read_bytes())
    return h.hexdigest()[:24]


def model_fingerprint(system_name: str, variant: str, model) -> str:
    """A key for a model known only as an object (typed interactively): its expressions,
    printed canonically (``srepr``), and the generator's files and tool versions."""
    import sympy as sp

    fields = (
        "q",
        "u",
        "params",
        "C",
        "D",
        "Q",
        "P",
        "nonholonomic",
        "holonomic",
        "u_independent",
        "energy",
        "outputs",
        "q_dependent",
        "monitors",
        "t",
    )
    text = "\0".join(sp.srepr(getattr(model, f)) for f in fields)
    h = hashlib.sha256(_tools_key(system_name, variant).encode())
    h.update(text.encode())
    return h.hexdigest()[:24]


def _tools_key(system_name: str, variant: str) -> str:
    from importlib.metadata import version

    h = hashlib.sha256(f"{system_name}\0{variant}\0{sys.version}".encode())
    for dist in ("sympy", "numba", "numpy"):
        h.update(version(dist).encode())
    here = Path(__file__).parent
    for f in _CORE_FILES:
        h.update((here / f).read_bytes())
    return h.hexdigest()


def kernel(fp: str | None, derive: Callable[[], object], label: tuple[str, str] = ("", "")) -> tuple[object, ModelInfo]:
    """The kernel module and model info for fingerprint ``fp``, from the disk cache when it
    is there (no sympy needed), otherwise derived, generated and cached.  ``label`` (system,
    variant) is recorded in the index for ``nmkane cache``."""
    index = cache_dir() / "index" / f"{fp}.json" if fp else None
    if index is not None and index.exists():
        try:
            import json

            entry = json.loads(index.read_text())
            key = entry["key"]
            with _LOCK:
                if key not in _LOADED:
                    folder = cache_dir() / key
                    if not (folder / f"nmkane_kernel_{key}.py").exists():
                        raise FileNotFoundError(key)
                    _LOADED[key] = _import(folder, key, None)
                    with contextlib.suppress(OSError):
                        os.utime(index)  # last use, for `nmkane cache prune --unused-days`
                return _LOADED[key], ModelInfo.from_json(json.dumps(entry["info"]))
        except (OSError, KeyError, ValueError, TypeError):
            pass  # a damaged entry: regenerate below
    d = derive()
    source = generate_source(d)
    module = compiled_kernel(d, source)
    info = ModelInfo.from_derivation(d)
    if index is not None:
        import json

        index.parent.mkdir(parents=True, exist_ok=True)
        tmp = index.with_suffix(f".tmp{os.getpid()}")
        tmp.write_text(
            json.dumps(
                {
                    "key": _source_key(source),
                    "system": label[0],
                    "variant": label[1],
                    "info": json.loads(info.to_json()),
                }
            )
        )
        os.replace(tmp, index)
    return module, info
