"""`nmkane figures`: every figure of the paper's two examples as a real, non-blank PNG, and a
report (Markdown, HTML, JSON) that shows each figure beside its claims and records runs
that can be re-run (issue 7).  Quick mode: shorter horizons where the claims allow it."""

import json
import os
import shlex
import struct
import subprocess
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest

from nmkane_core.paper import FAIL, PASS, run_plan
from nmkane_core.run.simulate import resolve

PAPER_FIGURES = [2, 3, 4, 5, 6, 7, 8, 9, 11, 12, 13, 14, 15, 16, 17, 18]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture
def report(quick_report):
    """The report of `nmkane figures --quick`, made once per session (tests/conftest.py)."""
    return quick_report


def _png_size(data: bytes) -> tuple[int, int]:
    assert data[:8] == PNG_SIGNATURE, "not a PNG file"
    length, kind = struct.unpack(">I4s", data[8:16])
    assert kind == b"IHDR" and length == 13
    width, height = struct.unpack(">II", data[16:24])
    crc = struct.unpack(">I", data[16 + length : 20 + length])[0]
    assert crc == zlib.crc32(data[12 : 16 + length]) & 0xFFFFFFFF, "corrupt IHDR chunk"
    return width, height


def test_every_paper_figure_is_written_once(report):
    assert [f.number for f in report.figures] == PAPER_FIGURES
    assert all(f.error is None for f in report.figures), [(f.number, f.error) for f in report.figures]
    names = [f.file for f in report.figures]
    assert len(set(names)) == len(names)


def _check_png_drawn(path: Path) -> None:
    """A real PNG of a plot with data on it: not blank, not an empty frame."""
    import matplotlib.image as mpimg

    data = path.read_bytes()
    width, height = _png_size(data)
    assert width >= 600 and height >= 400, (width, height)
    pixels = mpimg.imread(str(path))[..., :3]
    assert pixels.shape[:2] == (height, width)
    gray = pixels.mean(axis=2)
    assert gray.std() > 0.05, "image is (nearly) blank"
    assert (gray < 0.8).mean() > 0.01, "almost no ink"
    # the curves are coloured, the frame, ticks and text are not: an empty axes has no colour
    colour = pixels.max(axis=2) - pixels.min(axis=2)
    assert (colour > 0.2).mean() > 0.003, "no data drawn (no coloured pixels)"


@pytest.mark.parametrize("number", PAPER_FIGURES)
def test_figure_is_a_real_non_blank_png(report, number):
    fig = next(f for f in report.figures if f.number == number)
    _check_png_drawn(Path(report.out_dir) / fig.file)


@pytest.mark.parametrize("what", ["blank", "empty axes", "not a png"])
def test_png_check_rejects_blank_or_empty_figures(tmp_path, what):
    from matplotlib.figure import Figure

    path = tmp_path / "f.png"
    if what == "not a png":
        path.write_bytes(b"GIF89a" + bytes(100))
    else:
        fig = Figure(figsize=(7, 4.4), dpi=130)
        if what == "empty axes":
            fig.suptitle("Figure 2. Example 1: θ vs. t.")
            ax = fig.add_subplot(111)
            ax.set_xlabel("t (s)")
            ax.set_ylabel("θ (rad)")
        fig.savefig(path)
    with pytest.raises(AssertionError):
        _check_png_drawn(path)


def test_report_shows_each_figure_beside_its_claims(report):
    md = Path(report.files["md"]).read_text(encoding="utf-8")
    page = Path(report.files["html"]).read_text(encoding="utf-8")
    for fig in report.figures:
        assert f"## Figure {fig.number}" in md and f"]({fig.file})" in md
        assert f'<img src="{fig.file}"' in page
        assert "What this shows." in md
    for claim in report.claims:
        assert claim.status in (PASS, FAIL)
        assert claim.measured.replace("|", "\\|") in md
    assert md.count("**FAIL**") + md.count("**PASS**") >= 2 * len(report.claims)
    assert page.count("class='FAIL'") + page.count("class='PASS'") >= len(report.claims)
    # the paper's captions and the axis units are in the report and on the figures
    assert "*Figure 15. Example 2: Constraint violation, φ: Γ1 = −20, Γ2 = −100, Δt = 0.001 s.*" in md


def test_report_json_matches_the_claims_table(report):
    doc = json.loads(Path(report.files["json"]).read_text(encoding="utf-8"))
    assert [c["key"] for c in doc["claims"]] == [c.key for c in report.claims]
    assert [c["status"] for c in doc["claims"]] == [c.status for c in report.claims]
    assert {f["number"] for f in doc["figures"]} == set(PAPER_FIGURES)


def test_report_records_settings_that_rerun_through_the_rest_schema(report):
    plan = run_plan(quick=True)
    assert set(report.runs) == set(plan)
    for key, doc in report.runs.items():
        body = doc["rest"].split("-d '", 1)[1].rstrip("'")
        settings = json.loads(body)
        assert settings == plan[key]
        resolve(settings)  # the library (and so REST) accepts them as they are
        assert doc["summary"]["status"] == "ok"


def test_rest_limits_quoted_by_the_report_are_the_service_defaults(monkeypatch):
    """The report tells which runs need the REST limits raised; its numbers are the service's."""
    from backend.config import Settings
    from nmkane_core.schema import REST_DEFAULT_LIMITS

    monkeypatch.delenv("NMKANE_MAX_STEPS", raising=False)
    monkeypatch.delenv("NMKANE_MAX_ROWS", raising=False)
    service = Settings()
    assert {"max_steps": service.max_steps, "max_rows": service.max_rows} == REST_DEFAULT_LIMITS


def test_cli_command_in_the_report_reproduces_the_run(report, tmp_path):
    """Re-running a recorded `nmkane run ...` line gives the report's numbers exactly."""
    doc = report.runs["ah-linear"]
    argv = shlex.split(doc["cli"])
    assert argv[:2] == ["nmkane", "run"]
    out = tmp_path / "rerun.json"
    argv[argv.index("--out") + 1] = str(out)
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    proc = subprocess.run(
        [sys.executable, "-m", "nmkane_core.cli", *argv[1:], "--no-progress"],
        capture_output=True,
        text=True,
        env=env,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    rerun = json.loads(out.read_text())
    assert rerun["summary"]["max_abs_energy_drift"] == doc["summary"]["max_abs_energy_drift"]
    assert rerun["summary"]["steps"] == doc["summary"]["steps"]


def test_report_states_the_choices_the_paper_leaves_open(report):
    md = Path(report.files["md"]).read_text(encoding="utf-8")
    assert "the paper states neither" in md  # Appell–Hamel horizon and step
    assert "Fig. 18 over 100 s (not stated in the paper; quick mode)" in md
    assert "Figs. 11–15 and 17 over 500 s (the paper's)" in md


def test_report_takes_well_under_a_minute(report):
    assert report.timings["total_s"] < 60, report.timings


def test_summary_text_lists_every_claim(report):
    text = report.summary_text()
    for claim in report.claims:
        assert claim.claim in text
    assert "pass" in text and str(report.out_dir) in text
    n = report.counts
    assert n[PASS] + n[FAIL] == len(report.claims)
    assert np.isfinite(report.timings["total_s"])
