"""The sympy printer of the models' C functions (:mod:`~nmkane_core.kernel.native`)."""

from __future__ import annotations

__all__ = ["c_printer"]


def _power(printer, expr, sqrt: str) -> str | None:
    """Small integer powers as products or divisions (exact, and fast in compiled code), x^(1/2)
    as ``sqrt``; None for the printer's own rule."""
    import sympy as sp

    base, exp = expr.as_base_exp()
    if exp.is_Integer and 1 < abs(int(exp)) <= 4:
        b = printer.parenthesize(base, 100)
        prod = "*".join([b] * abs(int(exp)))
        return f"({prod})" if exp > 0 else f"(1.0/({prod}))"
    if exp == sp.S.Half:
        return f"{sqrt}({printer._print(base)})"
    return None


def c_printer():
    """C99 source (``math.h``); strict: a function C does not have raises instead of a comment."""
    from sympy.printing.c import C99CodePrinter

    class _Printer(C99CodePrinter):
        def _print_Pow(self, expr):
            return _power(self, expr, "sqrt") or super()._print_Pow(expr)

    return _Printer({"strict": True})
