"""Write the lesson notebooks (``lessons/*.ipynb``) from their sources (``lessons/src/*.py``).

A source is a plain Python file in the "percent" format: ``# %%`` starts a code cell and
``# %% [markdown]`` a text cell whose lines are comments (``# `` stripped).  The sources are
what is reviewed; the notebooks are generated, without outputs, so that they open in
Jupyter ready to run.  ``--check`` fails when a notebook is not what its source makes (the
tests run it).

    python scripts/make_lessons.py          # write lessons/*.ipynb
    python scripts/make_lessons.py --check  # exit 1 if any is out of date
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import nbformat

ROOT = Path(__file__).resolve().parents[1]
LESSONS = ROOT / "lessons"
MARK = "# %%"


def _cells(source: str) -> list[tuple[str, str]]:
    """(kind, text) of each cell of a percent-format source."""
    cells: list[tuple[str, list[str]]] = []
    for line in source.splitlines():
        if line.startswith(MARK):
            cells.append(("markdown" if "[markdown]" in line else "code", []))
        elif cells:
            cells[-1][1].append(line)
    out = []
    for kind, lines in cells:
        if kind == "markdown":
            lines = [ln[2:] if ln.startswith("# ") else ln.lstrip("#") for ln in lines]
        text = "\n".join(lines).strip("\n")
        if text:
            out.append((kind, text))
    return out


def notebook(source: str) -> nbformat.NotebookNode:
    """The notebook of one lesson source (no outputs; the python3 kernel)."""
    nb = nbformat.v4.new_notebook()
    for i, (kind, text) in enumerate(_cells(source)):
        make = nbformat.v4.new_markdown_cell if kind == "markdown" else nbformat.v4.new_code_cell
        nb.cells.append(make(text, id=f"cell-{i}"))
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    return nb


def targets() -> dict[Path, str]:
    """Each notebook path and the text its source makes."""
    return {
        LESSONS / f"{src.stem}.ipynb": nbformat.writes(notebook(src.read_text())) + "\n"
        for src in sorted((LESSONS / "src").glob("*.py"))
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="fail if a notebook is out of date")
    args = parser.parse_args(argv)
    stale = []
    for path, text in targets().items():
        if args.check:
            if not path.exists() or path.read_text() != text:
                stale.append(path.name)
        else:
            path.write_text(text)
            print(f"wrote {path.relative_to(ROOT)}")
    if stale:
        print(f"out of date (run scripts/make_lessons.py): {', '.join(stale)}", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
