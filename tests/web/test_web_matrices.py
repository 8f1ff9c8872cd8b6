"""The matrices panel's child process: long entries are elided, and the child dies with its parent."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests._helpers import require

require("matplotlib")
ROOT = Path(__file__).resolve().parents[2]


def test_entries_too_long_to_typeset_are_elided_and_said(monkeypatch):
    from web import matrices as mx

    monkeypatch.setattr(mx, "TYPESET_OPS", 2)
    p = mx._build("sliding-particle", "nonminimal")
    assert "too long to typeset" in p.intro and "nmkane matrices sliding-particle" in p.intro
    assert any("too long to show" in v for v in p.latex.values())
    assert p.images  # still drawn: the short entries and ⋯ for the others


def test_the_short_matrices_are_typeset_in_full():
    from web import matrices as mx

    p = mx._build("sliding-particle", "nonminimal")
    assert "too long" not in p.intro
    assert all(v.startswith(mx.TITLES[k]) for k, v in p.latex.items() if k != "where")


def test_a_model_without_a_square_j2_shows_j1_j2_and_q_and_says_why():
    """IFToMM A04's constraints are redundant: no A = −J2⁻¹J1, so no A1, A2, T (before: the
    panel was "matrices unavailable: The system is inconsistent.")."""
    from web import matrices as mx

    p = mx.panel("iftomm-a04", "default")
    assert list(p.images) == ["J1", "J2", "Q", "P"] and set(p.latex) >= {"J1", "J2", "Q", "P"}
    assert "Shown instead: J1, J2, Q and P (43)" in p.intro and "J2 is 5 × 4" in p.intro


def test_the_latex_is_the_simplified_form_and_nothing_is_elided():
    """The nonlinear Appell–Hamel model (the teacher's A1 was 4,359 characters unsimplified):
    simplified, with the denominators' sums named n_k and defined, and no entry drawn as ⋯."""
    from web import matrices as mx

    p = mx._build("appell-hamel", "nonlinear")
    assert "too long" not in p.intro and set(p.images) == {"A1", "A2", "T", "V"}
    assert len(p.latex["A1"]) < 1000, len(p.latex["A1"])
    assert "n_{1}" in p.latex["A1"] and p.latex["where"].startswith(r"\text{where } n_{1} =")
    assert all(r"\cdots" not in v for v in p.latex.values())


def test_a_wide_matrix_is_drawn_entry_by_entry_narrow_enough_to_read():
    """Example 1's T as a grid is 1,083 px wide, shown in a panel of about 345 px: wider than
    WIDE_PX a matrix is drawn as its nonzero entries one under another (issue 43, item 4)."""
    from web import matrices as mx

    p = mx._build("appell-hamel", "nonlinear")
    tall = {k for k, img in p.images.items() if img.shape[0] > img.shape[1]}  # entry by entry
    assert "T" in tall and "V" in p.images  # all four of item 4: A1, A2, T, V
    # a grid is never wider than WIDE_PX (how wide an entry is depends on how far the panel's time
    # budget simplified it: 512 px for T's widest here, A1 and A2 grids of 558 and 580 px)
    assert all(img.shape[1] <= mx.WIDE_PX for k, img in p.images.items() if k not in tall)
    grid = mx._matrix_or_entries("B", [["1", "0"], ["0", "x"]])
    assert grid.shape[1] < mx.WIDE_PX and grid.shape[0] < grid.shape[1]  # a small one stays a grid


def test_a_panel_finished_as_the_browser_leaves_is_written_inside_the_leave_scope():
    """The panel's background thread checked that the browser was there, then wrote a dozen
    images: a browser leaving in between put viser's "Queued a GuiUpdateMessage on a closed
    connection" warning into the server's log (seen in a shuffled full run, then 2 times in 12
    runs of the session-cap tests).  The writes now run in the session's ``racing_a_leave``
    scope, where those dropped messages are expected."""
    import contextlib
    import threading

    from web.panel import MatricesPanel

    inside, writes = [False], []

    @contextlib.contextmanager
    def racing_a_leave():
        inside[0] = True
        try:
            yield
        finally:
            inside[0] = False

    class Handle:  # a viser GUI handle: each attribute set is a message to the browser
        def __setattr__(self, name, value):
            writes.append((name, inside[0]))
            object.__setattr__(self, name, value)

    class Gui:
        def add_markdown(self, *args, **kwargs):
            return Handle()

        def add_image(self, *args, **kwargs):
            return Handle()

    panel = MatricesPanel(Gui(), threading.Lock(), lambda: True, racing_a_leave)
    writes.clear()
    panel.key = ("sliding-particle", "nonminimal")  # what show() sets before it starts the thread
    panel._fill("sliding-particle", "nonminimal")
    assert {name for name, _ in writes} >= {"content", "image", "visible"}
    assert all(scoped for _, scoped in writes), [name for name, scoped in writes if not scoped]


def test_ink_is_drawn_on_white_in_the_ink_colour_and_blended_between():
    """The panel's colours (web.matrices._to_rgba, through a table): no ink is opaque white,
    full ink the ink colour, and partial ink the blend of the two within one level of 255."""
    import numpy as np

    from web import matrices as mx

    ink = np.array([[0.0, 1.0, 0.5, 0.25], [-0.5, 1.5, 0.1, 0.9]], np.float32)
    rgba = mx._to_rgba(ink, color=(20, 40, 60))
    assert rgba.dtype == np.uint8 and rgba.shape == (2, 4, 4) and (rgba[..., 3] == 255).all()
    assert rgba[0, 0, :3].tolist() == [255, 255, 255] and rgba[1, 0, :3].tolist() == [255, 255, 255]
    assert rgba[0, 1, :3].tolist() == [20, 40, 60] and rgba[1, 1, :3].tolist() == [20, 40, 60]
    a = np.clip(ink, 0, 1)[..., None]
    exact = (1 - a) * 255 + a * np.array([20, 40, 60], float)
    assert np.abs(rgba[..., :3] - exact).max() <= 1.0


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    with open(f"/proc/{pid}/stat") as f:  # a zombie has finished
        return f.read().split(")")[-1].split()[0] != "Z"


# /proc is Linux's; CI (CI=true, Linux) always has it, and there the test must run
@pytest.mark.skipif(not Path("/proc").exists() and os.environ.get("CI") != "true", reason="needs /proc (Linux)")
def test_the_child_stops_when_its_parent_dies(tmp_path):
    """A server killed while the panel derives must not leave the derivation running."""
    out = tmp_path / "child.pid"
    parent = (
        "import os, threading, time\n"
        "from web import matrices as mx\n"
        "threading.Thread(target=mx._compute, args=('whipple-bicycle', 'default', None), daemon=True).start()\n"
        "while not mx._children: time.sleep(0.05)\n"
        f"open({str(out)!r}, 'w').write(str(next(iter(mx._children)).pid))\n"
        "os._exit(0)  # as SIGKILL would: no cleanup\n"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    subprocess.run([sys.executable, "-c", parent], env=env, check=True, timeout=60)
    pid = int(out.read_text())
    deadline = time.monotonic() + 30
    while _alive(pid) and time.monotonic() < deadline:
        time.sleep(0.2)
    alive = _alive(pid)
    if alive:
        os.kill(pid, 9)
    assert not alive, "the matrices child outlived its parent"


def test_unsimplified_entries_are_broken_across_lines_at_their_sums(monkeypatch):
    """When the panel's time budget runs out (a loaded machine), Example 1's entries stay as
    derived: T drawn entry by entry was 3,471 px wide and V 2,640 px, in a panel of about
    345 px.  Each entry wider than WIDE_PX is now set on lines of whole terms."""
    from nmkane_core.symbolic import shorten
    from web import matrices as mx

    real = shorten.Budget.__init__
    monkeypatch.setattr(mx.Budget, "__init__", lambda self, total_s=0.0, entry_s=0.0: real(self, 0.0, 0.0))
    p = mx._build("appell-hamel", "nonlinear")
    widths = {k: img.shape[1] for k, img in p.images.items()}
    assert max(widths.values()) <= 1.1 * mx.WIDE_PX, widths
    assert p.images["T"].shape[0] > 1.5 * p.images["T"].shape[1]  # more lines than before


def test_the_pieces_of_a_long_entry_keep_its_brackets_and_signs():
    import sympy as sp

    from web import matrices as mx

    a, b, c, d, x = sp.symbols("a b c d x")
    long = sum(sp.Symbol(f"w_{k}") * sp.cos(x) ** k for k in range(1, 40))
    e = -a * (b - c * (long + d)) / (a + b)
    tex = lambda v: sp.latex(v)  # noqa: E731
    pieces = mx._tokens(e, tex)
    joined = " ".join(pieces)
    assert len(pieces) > 3 and joined.count("(") == joined.count(")")
    assert pieces[0].startswith("-") and r"\dfrac" in pieces[0]  # −a/(a + b) (…: the sign and the front
    assert all(mx._tex_image(p).shape[1] <= mx.PIECE_PX for p in pieces[1:])
