"""The nmkane command: summaries, files, one-line errors with exit code 2."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest

from nmkane_core.cli import main

NMKANE = [sys.executable, "-m", "nmkane_core.cli"]


def test_run_prints_readable_summary(capsys):
    assert main(["run", "appell-hamel", "--dt", "0.05", "--t-final", "2", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "status   ok" in out and "max |ΔE|" in out and "rolling_speed" in out
    assert "max |λ|" in out and "max |F|  contact " in out and "thread " in out and "thread.tension" in out


@pytest.mark.parametrize("ext", ["json", "csv", "npz"])
def test_run_writes_files(tmp_path, ext):
    path = tmp_path / f"run.{ext}"
    assert (
        main(
            [
                "run",
                "sliding-particle",
                "--gamma1",
                "-20",
                "--gamma2",
                "-100",
                "--dt",
                "0.01",
                "--t-final",
                "1",
                "--out",
                str(path),
                "--no-progress",
            ]
        )
        == 0
    )
    if ext == "json":
        doc = json.loads(path.read_text())
        assert set(doc) >= {"system", "settings", "t", "state", "energy", "violation", "summary"}
        assert doc["settings"]["gamma1"] == -20 and len(doc["t"]) == 101
    elif ext == "csv":
        lines = path.read_text().splitlines()
        assert lines[0].split(",")[:5] == ["t", "x", "y", "u1", "u2"] and len(lines) == 102
    else:
        data = np.load(path)
        assert data["t"].shape == (101,) and "violation_surface" in data
        assert data["normal.normal"].shape == (101,) and data["normal.normal"][0] == pytest.approx(9.81 / 5**0.5)


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["run", "appell-hamel", "--dt", "0"], "--dt"),
        (["run", "appell-hamel", "--dt", "-1"], "--dt"),
        (["run", "appell-hamel", "--dt", "nan"], "--dt"),
        (["run", "appell-hamel", "--t-final", "inf"], "--t-final"),
        (["run", "appell-hamel", "--t-final", "0"], "--t-final"),
        (["run", "appell-hamel", "--dt", "1e-5", "--t-final", "1000"], "steps"),
        (["run", "appell-hamel", "--model", "cubic"], "nonlinear | linear"),
        (["run", "banana"], "appell-hamel | sliding-particle"),
        (["run", "appell-hamel", "--integrator", "euler"], "--integrator"),
        (["run", "appell-hamel", "--set", "rho=-3"], "--set rho"),
        (["run", "appell-hamel", "--set", "rho"], "NAME=VALUE"),
        (["run", "appell-hamel", "--init", "zz=1"], "--init zz"),
        (
            [
                "run",
                "appell-hamel",
                "--init",
                "theta=0",
                "--init",
                "phi=0",
                "--init",
                "x=0",
                "--init",
                "y=0",
                "--init",
                "z=30",
                "--init",
                "u1=1",
                "--init",
                "u2=1",
                "--init",
                "u3=2",
                "--init",
                "u4=5",
                "--init",
                "u5=-0.5",
            ],
            "residuals",
        ),
        (["run", "appell-hamel", "--out", "x.txt"], "--out"),
        (["run", "appell-hamel", "--projection", "magic"], "--projection"),
    ],
)
def test_bad_input_exits_2_with_one_line_naming_the_option(argv, needle):
    proc = subprocess.run(
        NMKANE + argv, capture_output=True, text=True, timeout=120, env={**os.environ, "PYTHONWARNINGS": "ignore"}
    )
    assert proc.returncode == 2, proc.stderr
    err = proc.stderr.strip().splitlines()
    assert len(err) == 1, proc.stderr
    assert needle in err[0] and "Traceback" not in proc.stderr


def test_singular_run_exits_1_with_message(capsys):
    assert main(["run", "appell-hamel", "--init", "u2=0", "--no-switching", "--no-progress"]) == 1
    assert "singular" in capsys.readouterr().out


def test_wheel_not_rolling_start_switches_models_and_lists_the_switches(capsys):
    assert main(["run", "appell-hamel", "--init", "u2=0", "--t-final", "3", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "switch   t = 0 s: nonlinear → linear" in out


def test_matrices_command_prints_A1(capsys):
    assert main(["matrices", "sliding-particle", "--matrix", "A1", "--latex"]) == 0
    assert "A_1" in capsys.readouterr().out


def test_matrices_command_prints_the_entries_simplified(capsys):
    """As text, each entry simplified within the command's time budget: the nonlinear
    Appell–Hamel A1 as derived has 205 operations, simplified 42."""
    import sympy as sp

    from nmkane_core.kernel.built import built
    from nmkane_core.run.registry import get_system

    assert main(["matrices", "appell-hamel", "--matrix", "A1", "--width", "1000"]) == 0
    out = capsys.readouterr().out
    derived = built(get_system("appell-hamel")).derivation().matrix("A1")
    short = derived.applyfunc(sp.simplify)
    assert short != derived
    assert out.endswith("\n\nA1 =\n" + sp.pretty(short, use_unicode=True, wrap_line=False) + "\n\n")
    assert out.startswith("partition: u_I = (u1, u2), declared by the model\n")  # the partition first


def test_a_matrix_wider_than_the_terminal_is_printed_entry_by_entry(capsys):
    """Example 1's T is a 246-column block: at 100 columns each nonzero entry is printed on its
    own (issue 43, item 4), every line of them within the width."""
    import sympy as sp

    from nmkane_core.kernel.built import built
    from nmkane_core.run.registry import get_system

    assert main(["matrices", "appell-hamel", "--matrix", "T", "--width", "100"]) == 0
    out = capsys.readouterr().out
    body = out.split("entry by entry", 1)[1]
    assert "T: 5×5, wider than 100 columns" in out
    T = built(get_system("appell-hamel")).derivation().matrix("T")
    nonzero = [(i, j) for i in range(5) for j in range(5) if sp.simplify(T[i, j]) != 0]
    assert [line for line in body.splitlines() if line.startswith("T[")] == [
        f"T[{i + 1},{j + 1}] =" for i, j in nonzero
    ]
    assert max(len(line) for line in body.splitlines()) <= 100


def test_bench_quick_measures_every_workload():
    """`nmkane bench --quick --json`: every workload of the compiled-kernels issue measured
    in this run (no timing asserted here: speed lives in the benchmark's own table)."""
    from nmkane_core.bench.rows import format_table

    out = subprocess.run(
        [sys.executable, "-m", "nmkane_core.cli", "bench", "--quick", "--json"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode in (0, 1), out.stderr[-2000:]  # 1 = a target missed, still a table
    doc = json.loads(out.stdout)
    rows = doc["rows"]
    names = " | ".join(r["workload"] for r in rows)
    for part in (
        "Kutta–Merson, dt=0.001",
        "sympy KanesMethod",
        "numpy reference",
        "called from Python",
        "fresh process",
        "first `nmkane run appell-hamel --t-final 20` after install",
        "interactive re-run",
        "adaptive Kutta–Merson",
        "Γ sweep",
        "runs, local executor",
        "user system (examples/isokinetic_bowl.py): first run",  # (lost once when bench/ moved a level down)
        "constraint forces on/off",
        "Whipple bicycle: 10 s",
        *(f"IFToMM A0{k} " for k in range(1, 6)),
    ):
        assert part in names, part
    _check_iftomm_rows([r for r in rows if r["workload"].startswith("IFToMM")])
    for r in rows:
        assert np.isfinite(r["wall_s"]) and r["wall_s"] > 0, r
        assert r["evals_per_s"] is None or r["evals_per_s"] > 0, r
    ratio = next(r for r in rows if "inside the compiled loop" in r["workload"])
    assert ratio["x_sympy"] > 1 and ratio["x_reference"] > 1  # the compiled path is the fast one
    table = format_table(rows)
    assert table.splitlines()[0].startswith("workload") and "evals/s" in table


def _check_iftomm_rows(rows):
    """One row per IFToMM problem: its CPU time, OpenSim 3.2's (none published for A05) and the
    error achieved, within the benchmark's 1e-3 where it has one (A01, A02)."""
    from nmkane_core.systems import iftomm_a01, iftomm_a02, iftomm_a03, iftomm_a04

    published = [m.OPENSIM_CPU_S for m in (iftomm_a01, iftomm_a02, iftomm_a03, iftomm_a04)] + [None]
    assert [r["opensim_cpu_s"] for r in rows] == published
    for r in rows:
        assert r["cpu_s"] > 0 and r["error"] and all(np.isfinite(v) for v in r["error"].values()), r
        assert "OpenSim 3.2" in r["note"], r
    assert rows[0]["error"]["P1_position"] < 1e-3
    assert rows[1]["error"]["B0_position"] < 1e-3 and rows[1]["error"]["B0_velocity"] < 1e-3
    assert rows[2]["error"]["angles_at_0.03"] < 1e-6 and rows[3]["error"]["energy_drift"] < 1e-6
    assert rows[4]["error"]["energy_increase"] < 1e-6


def test_slow_preparation_is_announced_and_quick_one_is_silent(monkeypatch):
    """Events, no fixed waits: the slow block ends once its notice is out; the quick blocks'
    timers are joined after they were cancelled, so a notice they would print is printed by then."""
    import io
    import re
    import threading

    from nmkane_core.cli import common, notice_if_slow

    timers = []

    class Recorded(threading.Timer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            timers.append(self)

    monkeypatch.setattr(common.threading, "Timer", Recorded)
    out = io.StringIO()
    with notice_if_slow("preparing x", after=0.05, stream=out):
        timers[-1].join(30)  # the notice is printed
    lines = out.getvalue().splitlines()
    assert lines[0] == "nmkane: preparing x …" and re.fullmatch(r"nmkane: ready in \d+\.\d s \(.*\)", lines[1])
    out = io.StringIO()
    with notice_if_slow("preparing y", after=0.5, stream=out):
        pass
    timers[-1].join(30)  # the cancelled timer ended without printing
    assert out.getvalue() == ""
    out = io.StringIO()
    with pytest.raises(ValueError), notice_if_slow("preparing z", after=0.05, stream=out):
        raise ValueError("bad input")
    timers[-1].join(30)
    assert out.getvalue() == ""
