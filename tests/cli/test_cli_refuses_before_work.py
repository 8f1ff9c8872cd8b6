"""The command refuses what it could not finish before doing the work (issue 44): an output
file in a missing folder, and a sweep seed outside [0, 2³² − 1], exit 2 with one line naming
the option — no run first, no traceback."""

import pytest

from nmkane_core.cli import main, run_cmd
from nmkane_core.cli.commands import all_commands


@pytest.fixture()
def no_run(monkeypatch):
    """Fail the test if a simulation starts."""

    def refuse(*args, **kwargs):
        raise AssertionError("the run started before its output was checked")

    # the commands' modules imported first: one that binds the name at its import (web's export)
    # would otherwise keep the refusing stand-in after this test, for the tests after it
    all_commands()
    monkeypatch.setattr(run_cmd, "simulate_from_args", refuse)


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    return err


def test_run_out_in_a_missing_folder_exits_2_before_running(no_run, capsys):
    code = main(["run", "sliding-particle", "--t-final", "0.1", "--no-progress", "--out", "/nonexistent/dir/r.json"])
    assert code == 2
    err = _one_line(capsys)
    assert "--out: got '/nonexistent/dir/r.json' (no folder /nonexistent/dir)" in err
    assert "allowed: a file in an existing folder" in err


def test_run_out_naming_a_folder_or_under_a_file_exits_2_before_running(tmp_path, no_run, capsys):
    (tmp_path / "d.json").mkdir()
    (tmp_path / "f.json").write_text("{}")
    for out, why in ((tmp_path / "d.json", "(a folder)"), (tmp_path / "f.json" / "r.json", "f.json is not a folder")):
        assert main(["run", "sliding-particle", "--no-progress", "--out", str(out)]) == 2
        assert why in _one_line(capsys)


def test_run_plot_into_a_missing_folder_exits_2_before_running(no_run, capsys):
    argv = ["run", "sliding-particle", "--no-progress", "--plot", "x", "--plot-out", "/nonexistent/p.png"]
    assert main(argv) == 2
    assert "--plot-out: got '/nonexistent/p.png' (no folder /nonexistent)" in _one_line(capsys)


@pytest.mark.parametrize("seed", ["-1", str(2**32), str(2**64)])
def test_sweep_seed_out_of_range_exits_2_with_one_line(tmp_path, capsys, seed):
    argv = ["sweep", "sliding-particle", "--t-final", "0.1", "--no-progress", "--workers", "1"]
    argv += ["--sample", "gamma2=-2:-1", "--samples", "2", "--seed", seed, "--out", str(tmp_path / "s.csv")]
    assert main(argv) == 2
    assert f"--seed: got {seed} (out of range); allowed: an integer in [0, 4294967295]" in _one_line(capsys)
    assert not (tmp_path / "s.csv").exists()  # nothing ran


def test_sweep_out_in_a_missing_folder_exits_2(capsys):
    argv = ["sweep", "sliding-particle", "--grid", "gamma1=-1,-2", "--out", "/nonexistent/dir/s.csv"]
    assert main(argv) == 2
    assert "--out: got '/nonexistent/dir/s.csv' (no folder /nonexistent/dir)" in _one_line(capsys)
