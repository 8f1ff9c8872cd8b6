"""The docs pages that teach by code run as written: each page's Python blocks are executed in
order in one fresh interpreter (a page cannot go stale), and the hand-written run-settings
table names exactly the fields of ``RunSettings``."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^```python\n(.*?)^```", re.MULTILINE | re.DOTALL)
PAGES = ["README.md", "docs/getting-started.md", "docs/your-own-system.md", "docs/forces.md"]


def python_blocks(page: str) -> list[str]:
    """The ```python blocks of a page at the top level (indented ones, e.g. a file included
    into a collapsible example, are not part of the page's session)."""
    text = (ROOT / page).read_text()
    return [b for b in FENCE.findall(text) if "--8<--" not in b]


@pytest.mark.parametrize("page", PAGES)
def test_the_python_blocks_of_the_page_run_as_written(page, tmp_path):
    blocks = python_blocks(page)
    assert blocks, f"{page} has no python block"
    # one interpreter per page, blocks in order: the registry of a test process stays clean
    script = tmp_path / "page.py"
    # compiled under the page's path: a system defined on the page is cached under its text
    program = "\n".join(f"exec(compile({block!r}, {page!r}, 'exec'), NS)" for block in blocks)
    script.write_text("NS = {'__name__': '__main__'}\n" + program + "\n")
    proc = subprocess.run([sys.executable, str(script)], cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-4000:]


def test_the_run_settings_table_names_every_field_of_run_settings():
    from nmkane_core import RunSettings

    text = (ROOT / "docs/cli.md").read_text()
    section = text.split("## Run settings", 1)[1].split("\n## ", 1)[0]
    named = set()
    for line in section.splitlines():
        if line.startswith("| `"):
            named.update(re.findall(r"`([a-z_0-9]+)`", line.split("|")[1]))
    fields = set(RunSettings.model_fields)
    assert named == fields, f"in the table, not a field: {sorted(named - fields)}; missing: {sorted(fields - named)}"


def test_every_public_name_gets_a_reference_page():
    sys.path.insert(0, str(ROOT / "scripts" / "docs"))
    try:
        import gen_reference
    finally:
        sys.path.pop(0)
    import nmkane_core

    pages = gen_reference.pages()
    assert {f"reference/{name}.md" for name in nmkane_core.__all__} <= set(pages)
    for name in nmkane_core.__all__:
        assert f"::: nmkane_core.{name}\n" in pages[f"reference/{name}.md"]
