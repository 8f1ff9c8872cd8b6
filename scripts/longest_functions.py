"""The longest functions of nmkane_core, backend and web.

    python scripts/longest_functions.py [COUNT]

Prints how many functions are over 100 and over 60 lines (docstrings not counted), then the COUNT longest (default 20),
as the house's rule counts them (tests/test_architecture.py).
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _code_lines(fn) -> int:
    """A function's lines without its docstring (documentation does not make code long)."""
    n = fn.end_lineno - fn.lineno + 1
    first = fn.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        n -= first.end_lineno - first.lineno + 1
    return n


def lengths() -> list[tuple[int, str]]:
    out = []
    for pkg in ("nmkane_core", "backend", "web"):
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    out.append((_code_lines(node), f"{path.relative_to(ROOT)}:{node.name}"))
    return sorted(out, reverse=True)


def main(count: int = 20) -> None:
    rows = lengths()
    print(f"over 100 lines: {sum(n > 100 for n, _ in rows)}, over 60 lines: {sum(n > 60 for n, _ in rows)}")
    for n, name in rows[:count]:
        print(f"{n:5d}  {name}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
