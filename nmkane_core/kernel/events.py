"""A system's declared events compiled into numpy functions (no sympy afterwards).

A system declares ``System(events=fn)`` where ``fn()`` (sympy inside: called only when the
compiled form is not cached yet) returns ``{name: expression}`` of the coordinates, speeds and
parameters (plain symbols or ``dynamicsymbols`` named like them), negative during the normal
motion.  :func:`compile_events` turns them into :class:`CompiledEvents`, cached under
``<cache root>/events/`` keyed by the system's kernel key and the file declaring the events;
:mod:`nmkane_core.run.events` applies them to finished runs.
"""

from __future__ import annotations

import threading

import numpy as np

from ..errors import InputError
from .built import built
from .cache import declared_data
from .visuals import _ident, _plain

__all__ = ["CompiledEvents", "compile_events"]

GENERATOR_VERSION = "1"
_MEMO: dict = {}
_LOCK = threading.Lock()


class CompiledEvents:
    """The events of a system as a numpy function: :meth:`values` (name → array over rows)."""

    def __init__(self, names: list[str], source: str):
        self.names = list(names)
        self.source = source
        self._ns: dict = {}
        exec(compile(source, "<nmkane events>", "exec"), self._ns)

    def values(self, states: dict, params: dict) -> dict[str, np.ndarray]:
        """Every event's value over the rows of ``states`` (name → array), for ``params`` (name → value)."""
        n = len(next(iter(states.values())))
        with np.errstate(all="ignore"):
            out = self._ns["events"]({k: np.asarray(v, float) for k, v in states.items()}, params)
        return {k: np.broadcast_to(np.asarray(v, float), (n,)) for k, v in zip(self.names, out, strict=True)}


def _generate(events: dict, state_names, param_names) -> str:
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    names = set(state_names) | set(param_names)
    exprs = []
    for k, e in events.items():
        try:
            e = _plain(e, names)
        except (sp.SympifyError, TypeError, AttributeError):
            raise InputError(
                f"events.{k}", e, "a sympy expression of the state and parameters", "not an expression"
            ) from None
        bad = sorted(s.name for s in e.free_symbols if s.name not in names)
        if bad:
            raise InputError(f"events.{k}", bad[0], "names of coordinates, speeds and parameters", "unknown name")
        exprs.append(e)
    used = set().union(*(e.free_symbols for e in exprs)) if exprs else set()
    exprs = [e.subs({s: sp.Symbol(_ident(s.name), real=True) for s in e.free_symbols}) for e in exprs]
    printer = NumPyPrinter({"fully_qualified_modules": True})
    lines = ["import functools", "import numpy", "", "", "def events(s, p):"]
    for sname in sorted(s.name for s in used):
        lines.append(f"    {_ident(sname)} = {'s' if sname in state_names else 'p'}[{sname!r}]")
    subs, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("_c"))
    lines += [f"    {sym} = {printer.doprint(e)}" for sym, e in subs]
    lines.append("    return [" + ", ".join(printer.doprint(e) for e in reduced) + "]")
    return "\n".join(lines) + "\n"


def compile_events(system) -> CompiledEvents | None:
    """A system's compiled events (None if it declares none): from memory, the disk cache,
    or generated (sympy) and cached.  ``system`` is a :class:`~nmkane_core.declare.system.System`."""
    if getattr(system, "events", None) is None:
        return None
    with _LOCK:
        memo = _MEMO.get(id(system))
        if memo is not None and memo[0] is system:
            return memo[1]

    def build() -> dict:
        declared = system.events()
        if not isinstance(declared, dict) or not all(isinstance(k, str) for k in declared):
            raise InputError(f"{system.name}: events", type(declared).__name__, "a function returning {name: expr}", "")
        info = built(system).info(system.default_variant)
        return {
            "names": list(declared),
            "source": _generate(declared, tuple(info.q) + tuple(info.u), system.param_names),
        }

    key = built(system).key(system.default_variant)
    data = declared_data(key, system.events, "events", __file__, GENERATOR_VERSION, build)
    compiled = CompiledEvents(data["names"], data["source"])
    with _LOCK:
        _MEMO[id(system)] = (system, compiled)
    return compiled
