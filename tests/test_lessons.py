"""The lessons (``lessons/*.ipynb``) run top to bottom without an error — each ends with
exercises whose answers its last cell checks with asserts — and are what their sources
(``lessons/src/*.py``, ``scripts/make_lessons.py``) make."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LESSONS = sorted((ROOT / "lessons").glob("*.ipynb"))
CELL_TIMEOUT = 600  # s: a first run on an empty cache derives and compiles the kernels


def test_there_are_lessons_and_each_has_checked_exercises():
    import nbformat

    assert len(LESSONS) >= 3
    for path in LESSONS:
        cells = nbformat.read(path, as_version=4).cells
        assert any(c.cell_type == "markdown" and c.source.startswith("## Exercises") for c in cells), path.name
        assert cells[-1].cell_type == "code" and "assert" in cells[-1].source, path.name


def test_the_notebooks_are_what_their_sources_make():
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts/make_lessons.py"), "--check"], capture_output=True, text=True
    )
    assert proc.returncode == 0, proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("path", LESSONS, ids=[p.stem for p in LESSONS])
def test_the_lesson_runs_top_to_bottom(path, monkeypatch):
    import nbformat
    from nbclient import NotebookClient

    monkeypatch.setenv("MPLBACKEND", "Agg")  # the kernel's own: no display
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")])))
    nb = nbformat.read(path, as_version=4)
    client = NotebookClient(nb, timeout=CELL_TIMEOUT, kernel_name="python3", resources={"metadata": {"path": ROOT}})
    client.execute()  # raises CellExecutionError (with the cell and its traceback) if a cell fails
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
