"""A systems file that calls sys.exit() while it loads (issue 44, item 9) is an error naming the
file — through ``--systems`` the command's one-line error with exit code 2, through
``NMKANE_SYSTEMS`` and entry points one line on stderr — and no longer ends the command,
silently, with the file's exit code."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from nmkane_core import InputError

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture
def exits(tmp_path) -> Path:
    path = tmp_path / "exits_systems.py"
    path.write_text("import sys\n\nsys.exit(3)\n")
    return path


def test_loading_a_file_that_calls_sys_exit_is_a_plugin_error_naming_the_file(exits):
    from nmkane_core.run.plugins import load_systems

    errors = load_systems([str(exits)])
    assert len(errors) == 1
    assert errors[0].source == str(exits)
    assert str(errors[0]) == f"nmkane: systems from {exits} not loaded: SystemExit: it called sys.exit(3) while loading"


def test_strict_loading_raises_an_input_error_naming_the_file(exits):
    from nmkane_core.run.plugins import load_systems

    with pytest.raises(InputError) as info:
        load_systems([str(exits)], strict=True)
    assert info.value.field == "systems" and info.value.value == str(exits)
    assert "sys.exit(3)" in str(info.value)


def test_an_entry_point_that_exits_is_reported_not_obeyed(monkeypatch):
    from importlib.metadata import EntryPoint

    from nmkane_core.run import plugins

    ep = EntryPoint(name="quitter", value="sys:exit", group=plugins.ENTRY_POINT_GROUP)  # calls sys.exit()
    monkeypatch.setattr(plugins, "entry_points", lambda group: [ep] if group == plugins.ENTRY_POINT_GROUP else [])
    errors = plugins._from_entry_points()
    assert [e.source for e in errors] == ["entry point quitter (sys:exit)"]
    assert "SystemExit" in errors[0].error


def test_the_cli_main_returns_2_with_one_line(exits, capsys):
    from nmkane_core.cli import main

    assert main(["run", "sliding-particle", "--systems", str(exits), "--no-progress"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(exits) in err[0] and "sys.exit(3)" in err[0]


@pytest.mark.heavy  # the command in a subprocess: its real exit code
def test_the_command_exits_2_with_one_line_not_3_in_silence(exits):
    proc = subprocess.run(
        [sys.executable, "-m", "nmkane_core.cli", "run", "sliding-particle", "--systems", str(exits), "--no-progress"],
        capture_output=True,
        text=True,
        timeout=300,
        env=os.environ.copy(),
        cwd=ROOT,
    )
    assert proc.returncode == 2, (proc.returncode, proc.stderr)
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "exits_systems.py" in lines[0] and "sys.exit(3)" in lines[0], proc.stderr
    assert proc.stdout == ""
