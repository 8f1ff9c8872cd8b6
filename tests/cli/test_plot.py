"""``nmkane run ... --plot Y[:X]``: a PNG of any quantity against time or another; bad
expressions refused in one line that lists the names a run offers."""

import os
import subprocess
import sys

import numpy as np
import pytest

from nmkane_core.cli import main

NMKANE = [sys.executable, "-m", "nmkane_core.cli"]
RUN = ["run", "knife-edge", "--t-final", "4", "--no-progress"]


def _pixels(path):
    import matplotlib.image as mpimg

    return np.asarray(mpimg.imread(path))


def test_plot_against_time_and_a_phase_portrait_write_a_png(tmp_path, capsys):
    out = tmp_path / "p.png"
    argv = [*RUN, "--plot", "phi_no_side_slip", "--plot", "y:x", "--plot", "sqrt(u1^2+u2^2)", "--plot-out", str(out)]
    assert main(argv) == 0
    assert f"plot -> {out}" in capsys.readouterr().out
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 10_000
    img = _pixels(out)
    assert img.shape[0] > img.shape[1]  # three panels stacked: taller than wide
    assert np.std(img[..., :3]) > 0.05  # lines and labels, not a blank canvas


def test_phase_portrait_draws_the_second_expression_on_x():
    from nmkane_core import simulate
    from nmkane_core.cli import plot_out

    run = simulate({"system": "knife-edge", "t_final": 4})
    (xlab, xs, ylab, ys), (tlab, ts, _, _) = plot_out.panels(run, ["y:x", "u1*cos(theta)"])
    assert (xlab, ylab, tlab) == ("x", "y", "t [s]")
    np.testing.assert_allclose(xs, run.state["x"])
    np.testing.assert_allclose(ys, run.state["y"])
    np.testing.assert_allclose(ts, run.t)


def test_default_file_is_named_after_the_system(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main([*RUN, "--plot", "dE"]) == 0
    assert "plot -> knife-edge-plot.png" in capsys.readouterr().out
    assert (tmp_path / "knife-edge-plot.png").stat().st_size > 5_000


@pytest.mark.parametrize(
    ("plot", "needle"),
    [
        ("phi_c1", "unknown name 'phi_c1'"),
        ("__import__('os').system('true')", "only these functions"),
        ("x:y:t", "bad form"),
        ("theta.real", "attribute is not allowed"),
    ],
)
def test_bad_expression_exits_2_naming_the_option_and_the_names(plot, needle, tmp_path):
    proc = subprocess.run(
        [*NMKANE, *RUN, "--plot", plot, "--plot-out", str(tmp_path / "p.png")],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )
    assert proc.returncode == 2, proc.stderr
    err = [line for line in proc.stderr.strip().splitlines() if not line.startswith("nmkane: ")]
    assert len(err) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert err[0].startswith("nmkane run: error: --plot: got ") and needle in err[0], err[0]
    if needle != "bad form":
        for name in ("t", "x", "theta", "u1", "E", "dE", "phi_no_side_slip", "F_u1", "R_blade_lateral"):
            assert f" {name}," in err[0] or f" {name} " in err[0], name
    assert not (tmp_path / "p.png").exists()


def test_plot_out_must_be_a_png(capsys):
    assert main([*RUN, "--plot", "x", "--plot-out", "p.pdf"]) == 2
    assert "--plot-out: got 'p.pdf'" in capsys.readouterr().err
