"""The house's layering: imports run one way, no package has import circles (import-linter's
contracts), generic code names no system, modules and functions stay small, and
``import nmkane_core`` loads none of the faces' heavy dependencies."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("nmkane_core", "backend", "web")
MAX_LINES = 500


def test_the_layer_contracts_hold():
    """Imports run one way — faces on the core, each stage of the core on the stages below it —
    and no package has an import circle, imports for type checkers included (the contracts in
    pyproject.toml, checked by import-linter; ``make lint`` runs it too)."""
    lint = Path(sys.executable).with_name("lint-imports")
    out = subprocess.run([str(lint)], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout, out.stdout


GENERIC_WORDS = {"edge", "disk", "rolling", "particle"}  # words of system names that are ordinary mechanics
#: the parts of the core that may name a system: the systems themselves, the paper's figures, the benchmarks
NAMED_SYSTEMS_ALLOWED = ("systems", "paper", "bench")


def _system_words() -> set[str]:
    from nmkane_core.systems import BUILTIN

    words = set(BUILTIN)
    for name in BUILTIN:
        words |= {w for w in name.split("-") if len(w) > 3 and w not in GENERIC_WORDS}
    return words | {"appell", "hamel", "bicycle", "sleigh"}


def test_generic_core_code_names_no_system():
    """Nothing about a specific mechanism in generic code: outside the systems' own modules,
    the paper's figures and the benchmarks, no source file of the core (code, comments or
    docstrings) names a built-in system or a word of one (as tests/web/test_web_names_no_system.py
    checks web/)."""
    import re

    words = _system_words()
    assert {"appell-hamel", "whipple", "chaplygin"} <= words
    found = []
    for path in sorted((ROOT / "nmkane_core").rglob("*.py")):
        rel = path.relative_to(ROOT / "nmkane_core")
        if rel.parts[0] in NAMED_SYSTEMS_ALLOWED:
            continue
        text = path.read_text(encoding="utf-8").lower().replace("appell–chetaev", "")  # a name of mechanics
        for w in sorted(words):
            for m in re.finditer(re.escape(w), text):
                found.append(f"{rel}:{text.count(chr(10), 0, m.start()) + 1}: {w!r}")
    assert not found, "generic core code names systems:\n" + "\n".join(found)


MAX_FUNCTION_LINES, LONG_FUNCTION_LINES, MAX_LONG_FUNCTIONS = 100, 60, 10


def _code_lines(fn) -> int:
    """A function's lines without its docstring (documentation does not make code long)."""
    n = fn.end_lineno - fn.lineno + 1
    first = fn.body[0]
    if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
        n -= first.end_lineno - first.lineno + 1
    return n


def _function_lengths() -> list[tuple[int, str]]:
    """(lines, file:function) of every function of the three packages."""

    out = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            for node in ast.walk(ast.parse(path.read_text())):
                if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                    out.append((_code_lines(node), f"{path.relative_to(ROOT)}:{node.name}"))
    return sorted(out, reverse=True)


def test_functions_are_short_enough_to_read():
    """No function over 100 lines, and at most 10 over 60,
    docstrings not counted (``python scripts/longest_functions.py`` lists them)."""
    lengths = _function_lengths()
    too_long = [f"{n} {name}" for n, name in lengths if n > MAX_FUNCTION_LINES]
    long = [f"{n} {name}" for n, name in lengths if n > LONG_FUNCTION_LINES]
    assert not too_long, "\n".join(too_long)
    assert len(long) <= MAX_LONG_FUNCTIONS, "\n".join(long)


def test_no_hand_written_module_is_too_big():
    big = [
        f"{p.relative_to(ROOT)}: {n} lines"
        for pkg in (*PACKAGES, "tests", "scripts")
        for p in sorted((ROOT / pkg).rglob("*.py"))
        if (n := len(p.read_text().splitlines())) > MAX_LINES
    ]
    assert not big, "\n".join(big)


def test_importing_the_core_loads_no_face_dependency():
    code = (
        "import sys, nmkane_core, nmkane_core.cli\n"
        "heavy = {'fastapi', 'uvicorn', 'viser', 'matplotlib', 'starlette', 'backend', 'web'}\n"
        "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip() == "[]", out.stdout


def test_the_repository_does_not_point_outside_itself():
    """Someone who clones the repository has none of the team's shared folder."""
    files = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    outside = "../" + "shared"
    bad = [
        f
        for f in files
        if (ROOT / f).is_file()
        and Path(f).suffix in {".py", ".md", ".toml", ".txt", ""}
        and outside in (ROOT / f).read_text(errors="ignore")
    ]
    assert not bad, bad
