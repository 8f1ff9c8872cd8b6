"""A system's declared point forces (:mod:`nmkane_core.declare.forces`) compiled into numpy functions.

:func:`compile_forces` turns one variant's declaration into :class:`CompiledForces`: a table
of the forces (names, component labels, route, what they act on) and generated numpy source
with two functions — ``components(s, p, lam, fc, r, t)`` (the force components over many rows:
``s`` state name → array, ``lam`` constraint → λ, ``fc`` speed → F_c, ``r`` coordinate or
speed → its rate) and ``geometry(s, p)`` (the points where they act and the axes of their
components).  The source is cached on disk under ``<cache root>/forces/`` keyed by the
variant's kernel key (:meth:`nmkane_core.kernel.built.Built.key`), the file declaring the
forces and this generator, so a later process evaluates forces without sympy.
"""

from __future__ import annotations

import inspect
import threading
from dataclasses import dataclass, field

import numpy as np

from ..declare.forces import FC_PREFIX, LAMBDA_PREFIX, RATE_PREFIX, Forces
from ..errors import InputError
from .built import built
from .cache import declared_data

__all__ = ["CompiledForces", "compile_forces", "declared_forces"]

GENERATOR_VERSION = "1"
_MEMO: dict = {}
_LOCK = threading.Lock()


@dataclass
class CompiledForces:
    """The point forces of one variant as numpy functions (no sympy).

    ``forces``: one dict per force — ``name``, ``labels``, ``columns`` (``NAME.LABEL``),
    ``route``, ``on``, ``description``; ``multipliers``, ``generalized``, ``rates``: the
    constraint, speed and state names whose λ, F_c and rates the components use (a caller
    computes only those); ``scale``, ``show``: the declaration's drawing hints."""

    forces: list[dict]
    source: str
    multipliers: list[str]
    generalized: list[str]
    rates: list[str]
    scale: float | None = None
    show: bool = True
    _ns: dict = field(default_factory=dict, repr=False)

    def __post_init__(self):
        exec(compile(self.source, "<nmkane forces>", "exec"), self._ns)

    @property
    def columns(self) -> list[str]:
        """Every reported component name, ``NAME.LABEL``, in declaration order."""
        return [c for f in self.forces for c in f["columns"]]

    def components(
        self,
        states: dict,
        params: dict,
        multipliers: dict | None = None,
        generalized: dict | None = None,
        rates: dict | None = None,
        t=0.0,
    ) -> dict[str, np.ndarray]:
        """Every component (``NAME.LABEL`` → array over the rows of ``states``)."""
        n = len(next(iter(states.values())))
        with np.errstate(all="ignore"):
            out = self._ns["components"](
                _arrays(states),
                params,
                _arrays(multipliers),
                _arrays(generalized),
                _arrays(rates),
                np.asarray(t, float),
            )
        return {k: _column(v, n) for k, v in zip(self.columns, out, strict=True)}

    def geometry(self, states: dict, params: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Force name → (points (n, 3) where it acts, axes (n, 3, k) of its components), world coordinates."""
        n = len(next(iter(states.values())))
        with np.errstate(all="ignore"):
            out = self._ns["geometry"]({k: np.asarray(v, float) for k, v in states.items()}, params)
        vals = [np.broadcast_to(np.asarray(v, float), (n,)) for v in out]
        geo, i = {}, 0
        for f in self.forces:
            k = len(f["labels"])
            point = np.stack(vals[i : i + 3], axis=1)
            axes = np.stack(vals[i + 3 : i + 3 + 3 * k], axis=1).reshape(n, k, 3).transpose(0, 2, 1)
            geo[f["name"]] = (point, axes)
            i += 3 + 3 * k
        return geo

    def vectors(self, components: dict, states: dict, params: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Force name → (points (n, 3), force vectors (n, 3)) in world coordinates: the axes
        times the components (``components`` as :meth:`components` returns them)."""
        out, geo = {}, self.geometry(states, params)
        for f in self.forces:
            point, axes = geo[f["name"]]
            c = np.stack([np.asarray(components[col], float) for col in f["columns"]], axis=1)
            out[f["name"]] = (point, np.einsum("nij,nj->ni", axes, c))
        return out

    def magnitudes(self, components: dict) -> dict[str, np.ndarray]:
        """Force name → |R| over the rows (the axes are orthonormal: the components' norm)."""
        with np.errstate(over="ignore"):  # a diverged run's last rows: inf, reported as such
            return {
                f["name"]: np.sqrt(sum(np.asarray(components[c], float) ** 2 for c in f["columns"]))
                for f in self.forces
            }


def _arrays(values: dict | None) -> dict:
    return {k: np.asarray(v, float) for k, v in (values or {}).items()}


def _column(v, n: int) -> np.ndarray:
    """A component as an array of its own of n rows (a constant expression gives a scalar)."""
    if isinstance(v, np.ndarray) and v.shape == (n,) and v.dtype == np.float64:
        return v.copy()
    return np.broadcast_to(np.asarray(v, float), (n,)).copy()


def declared_forces(system, variant: str):
    """Call a system's ``forces`` declaration for ``variant`` (it takes the variant name, or nothing)."""
    fn = system.forces
    try:
        takes = len(inspect.signature(fn).parameters) > 0
    except (TypeError, ValueError):
        takes = True
    declared = fn(variant) if takes else fn()
    if not isinstance(declared, Forces):
        raise InputError(f"{system.name}: forces", type(declared).__name__, "a function returning Forces", "not Forces")
    return declared


def _plain(expr, names: set[str], where: str):
    """A component's expression in plain symbols: ``Derivative(f(t), t)`` of a dynamicsymbol
    becomes :func:`~nmkane_core.declare.forces.rate` of its name, ``f(t)`` the symbol ``f``."""
    import sympy as sp

    try:
        expr = sp.sympify(expr)
    except (sp.SympifyError, TypeError):
        raise InputError(where, expr, "a sympy expression", "not an expression") from None
    derivs = {}
    for d in expr.atoms(sp.Derivative):
        f = d.expr
        if not isinstance(f, sp.core.function.AppliedUndef) or len(d.variables) != 1:
            raise InputError(
                where, str(d), "first time derivatives of coordinates or speeds only (use rate(name))", "unsupported"
            )
        derivs[d] = sp.Symbol(RATE_PREFIX + f.func.__name__, real=True)
    if derivs:
        expr = expr.xreplace(derivs)
    funcs = {
        f: sp.Symbol(f.func.__name__, real=True)
        for f in expr.atoms(sp.Function)
        if isinstance(f, sp.core.function.AppliedUndef)
    }
    if funcs:
        expr = expr.xreplace(funcs)
    return expr.xreplace({s: sp.Symbol(s.name, real=True) for s in expr.free_symbols if s.name in names})


_KINDS = {LAMBDA_PREFIX: "lam", FC_PREFIX: "fc", RATE_PREFIX: "r"}  # symbol prefix → the source dict
_WHAT = {"lam": "constraint", "fc": "speed", "r": "coordinate or speed"}


class _Names:
    """The names a declaration may use, and which of the run's λ, F_c and rates it does use."""

    def __init__(self, info, param_names):
        self.model = info.name or "model"
        self.state = tuple(info.q) + tuple(info.u) + tuple(info.outputs)
        self.plain = set(self.state) | set(param_names) | {"t"}
        self.source = dict.fromkeys(self.state, "s") | dict.fromkeys(param_names, "p") | {"t": "t"}
        self.valid = {"lam": info.constraint_names, "fc": info.u, "r": tuple(info.q) + tuple(info.u)}
        self.used: dict[str, set[str]] = {"lam": set(), "fc": set(), "r": set()}

    def special(self, name: str) -> tuple[str, str] | None:
        """(kind, key) of a multiplier(), generalized() or rate() symbol's name, else None."""
        for prefix, kind in _KINDS.items():
            if name.startswith(prefix):
                return kind, name[len(prefix) :]
        return None

    def checked(self, expr, where: str, with_forces: bool):
        """``expr`` in plain symbols, every symbol a name it may use (else InputError naming ``where``)."""
        e = _plain(expr, self.plain, where)
        for s in e.free_symbols:
            if s.name in self.source:
                continue
            special = self.special(s.name) if with_forces else None
            if special is None:
                extra = ", multiplier(), generalized(), rate()" if with_forces else ""
                allowed = "names of coordinates, speeds, outputs, parameters and t" + extra
                raise InputError(where, s.name, allowed, "unknown name")
            kind, key = special
            if key not in self.valid[kind]:
                raise InputError(where, key, f"a {_WHAT[kind]} of the {self.model}: {', '.join(self.valid[kind])}")
            self.used[kind].add(key)
        return e

    def lookup(self, s) -> str:
        """Where the generated source reads a symbol's value from."""
        if s.name in self.source:
            src = self.source[s.name]
            return "t" if src == "t" else f"{src}[{s.name!r}]"
        special = self.special(s.name)
        assert special is not None, s
        return f"{special[0]}[{special[1]!r}]"


def _expressions(decl: Forces, names: _Names) -> tuple[list, list, list[dict]]:
    """(component expressions, geometry expressions — each force's point, then its axes column
    by column —, the force table) of a declaration, every symbol checked."""
    import sympy as sp

    comp, geo, table = [], [], []
    for f in decl.forces:
        where = f"forces.{f.name}"
        k = len(f.components)
        comp += [names.checked(c, f"{where}.components", True) for c in f.components]
        geo += [names.checked(c, f"{where}.at", False) for c in f.at]
        axes = sp.eye(3)[:, :k] if f.frame is None else sp.Matrix(f.frame)
        if axes.shape == (3, 3) and k < 3:
            axes = axes[:, :k]
        if axes.shape != (3, k):
            raise InputError(f"{where}.frame", axes.shape, f"a 3×{k} matrix (one column per component)", "bad shape")
        geo += [names.checked(axes[i, j], f"{where}.frame", False) for j in range(k) for i in range(3)]
        table.append(
            {
                "name": f.name,
                "labels": list(f.labels),
                "columns": list(f.columns),
                "route": f.route,
                "on": f.on,
                "description": f.description,
            }
        )
    return comp, geo, table


def _source(comp: list, geo: list, names: _Names) -> str:
    """numpy source of ``components(s, p, lam, fc, r, t)`` and ``geometry(s, p, t)``."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    idents: dict = {}

    def ident(s) -> str:
        if s not in idents:
            idents[s] = f"a{len(idents)}_" + "".join(c if c.isascii() and c.isalnum() else "_" for c in s.name)
        return idents[s]

    printer = NumPyPrinter({"fully_qualified_modules": True})

    def body(fn, args, exprs):
        syms = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
        lines = [f"def {fn}({args}):"]
        lines += [f"    {ident(s)} = {names.lookup(s)}" for s in sorted(syms, key=lambda s: s.name)]
        renamed = [e.xreplace({s: sp.Symbol(ident(s), real=True) for s in e.free_symbols}) for e in exprs]
        subs, reduced = sp.cse(renamed, symbols=sp.numbered_symbols("_c"))
        lines += [f"    {sym} = {printer.doprint(e)}" for sym, e in subs]
        lines.append("    return [" + ", ".join(printer.doprint(e) for e in reduced) + "]")
        return lines

    src = ["import functools", "import numpy", "", ""]
    src += [*body("components", "s, p, lam, fc, r, t", comp), "", ""]
    src += [*body("geometry", "s, p, t=0.0", geo), ""]
    return "\n".join(src)


def _generate(decl: Forces, info, param_names) -> dict:
    """The force table and numpy source of one variant's declaration (sympy)."""
    names = _Names(info, param_names)
    comp, geo, table = _expressions(decl, names)
    return {
        "forces": table,
        "source": _source(comp, geo, names),
        "multipliers": sorted(names.used["lam"]),
        "generalized": sorted(names.used["fc"]),
        "rates": sorted(names.used["r"]),
        "scale": decl.scale,
        "show": bool(decl.show),
    }


def compile_forces(system, variant: str | None = None) -> CompiledForces | None:
    """A variant's compiled point forces (None if the system declares none, or none for this
    variant): from memory, the disk cache, or generated (sympy) and cached.  ``system`` is a
    :class:`~nmkane_core.declare.system.System`; ``variant`` None: its default variant."""
    if getattr(system, "forces", None) is None:
        return None
    variant = system.check_variant(variant)
    with _LOCK:
        memo = _MEMO.get((id(system), variant))
        if memo is not None and memo[0] is system:
            return memo[1]

    def build() -> dict:
        decl = declared_forces(system, variant)
        return _generate(decl, built(system).info(variant), system.param_names)

    key = built(system).key(variant)
    data = declared_data(key, system.forces, "forces", __file__, GENERATOR_VERSION, build)
    compiled = CompiledForces(**data) if data["forces"] else None
    with _LOCK:
        _MEMO[(id(system), variant)] = (system, compiled)
    return compiled
