"""Small Markdown helpers shared by the page generators."""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from pathlib import Path

DOCS = Path(__file__).resolve().parents[2] / "docs"
MARKER = re.compile(r"^<!-- nmkane:([a-z0-9-]+) -->$", re.MULTILINE)


def cell(value: object) -> str:
    """One table cell: pipes escaped outside code spans (inside them a table keeps them), newlines folded."""
    text = "" if value is None else str(value)
    parts = text.replace("\n", " ").split("`")
    return "`".join(p if i % 2 else p.replace("|", "\\|") for i, p in enumerate(parts))


def table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A Markdown table; every cell goes through `cell` here (callers pass raw text)."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def code(value: object) -> str:
    return f"`{value}`"


def number(x: object) -> str:
    if isinstance(x, float):
        return f"{x:g}"
    return str(x)


def fill(page: str, parts: dict[str, str]) -> str:
    """The hand-written page ``docs/<page>`` with each ``<!-- nmkane:NAME -->`` line replaced by
    ``parts[NAME]``; a marker without a part, or a part without a marker, is an error."""
    text = (DOCS / page).read_text()
    found = set(MARKER.findall(text))
    if found != set(parts):
        raise RuntimeError(f"docs/{page}: markers {sorted(found)} but generated parts {sorted(parts)}")
    return MARKER.sub(lambda m: parts[m.group(1)].rstrip("\n"), text)
