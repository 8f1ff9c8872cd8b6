"""The house's layering: imports run one way, the core has no import circles, modules stay
small, and ``import nmkane_core`` loads none of the faces' heavy dependencies."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("nmkane_core", "backend", "web")
MAX_LINES = 500


def _modules(package: str) -> dict[str, Path]:
    out = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        rel = path.relative_to(ROOT).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _type_checking_lines(tree: ast.AST) -> set[int]:
    lines: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for child in node.body:
                lines.update(range(child.lineno, (child.end_lineno or child.lineno) + 1))
    return lines


def _imports(module: str, path: Path) -> set[str]:
    """Every module ``module`` imports, at any depth of its code (lazy imports count too),
    except imports only for type checkers."""
    tree = ast.parse(path.read_text())
    skip = _type_checking_lines(tree)
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out: set[str] = set()
    for node in ast.walk(tree):
        if getattr(node, "lineno", None) in skip:
            continue
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                target = ".".join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ""
            out.add(target)
            out.update(f"{target}.{a.name}" for a in node.names)  # `from . import x` names a module
    return out


def _top(name: str) -> str:
    return name.split(".")[0]


@pytest.mark.parametrize(
    "package,forbidden",
    [
        ("nmkane_core", {"backend", "web"}),
        ("backend", {"web"}),
        ("web", {"backend"}),
    ],
)
def test_imports_run_one_way(package, forbidden):
    bad = [f"{m} imports {i}" for m, p in _modules(package).items() for i in _imports(m, p) if _top(i) in forbidden]
    assert not bad, "\n".join(bad)


def test_the_core_has_no_import_circles():
    mods = _modules("nmkane_core")
    graph = {m: {i for i in _imports(m, p) if i in mods and i != m} for m, p in mods.items()}
    # a package's __init__ re-exporting its children is not a circle of responsibilities
    graph = {m: {i for i in deps if not m.startswith(i + ".")} for m, deps in graph.items()}
    cycles, state = [], {}

    def visit(m, stack):
        state[m] = 1
        for n in sorted(graph[m]):
            if state.get(n) == 1:
                cycles.append(" -> ".join([*stack[stack.index(n) :], n]))
            elif n not in state:
                visit(n, [*stack, n])
        state[m] = 2

    for m in sorted(graph):
        if m not in state:
            visit(m, [m])
    assert not cycles, "\n".join(cycles)


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
