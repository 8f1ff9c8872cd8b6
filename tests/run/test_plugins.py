"""Plug-in systems: a user's systems file reaches the CLI, the REST service and a fresh
process through ``--systems``, ``NMKANE_SYSTEMS`` and the ``nmkane.systems`` entry points;
kernels are cached by the model (no sympy in a later process; a changed model never loads
a stale kernel); a broken file is one clear line, and the others still load."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
BOWL = ROOT / "examples" / "isokinetic_bowl.py"
SKATE = ROOT / "examples" / "skate_on_incline.py"
NMKANE = [sys.executable, "-m", "nmkane_core.cli"]


def nmkane(*args, env=None, timeout=600):
    return subprocess.run(
        [*NMKANE, *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, **(env or {})},
        cwd=ROOT,
    )


def test_examples_run_through_systems_option_and_conserve_what_they_should():
    proc = nmkane("run", "isokinetic-bowl", "--systems", BOWL, "--t-final", "5", "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert "status   ok" in proc.stdout
    # the drive keeps the kinetic energy m v0²/2 (the reported energy) constant
    drift = float(proc.stdout.split("max |ΔE| = ")[1].split(",")[0])
    assert drift < 1e-9
    skate = nmkane("run", "skate-on-incline", "--systems", SKATE, "--t-final", "5", "--no-progress")
    assert skate.returncode == 0 and "no_side_slip" in skate.stdout, skate.stderr


def test_skate_on_incline_does_not_run_away_downhill(tmp_path):
    """Neimark & Fufaev: with θ = ωt the downhill coordinate stays within g sin α/ω² (here
    9.81·sin 0.2/4 ≈ 0.49 m) of its start, while y drifts sideways at g sin α/(2ω)."""
    from nmkane_core import simulate
    from nmkane_core.run.plugins import load_systems

    assert load_systems([str(SKATE)]) == []
    run = simulate(
        {"system": "skate-on-incline", "t_final": 20.0, "every": 10, "initial": {"theta": 0.0, "u1": 0.0, "u3": 2.0}}
    )
    assert run.status == "ok"
    assert run.state["x"].max() - run.state["x"].min() <= 9.81 * 0.19866933 / 4.0 * 1.001
    mean_vy = (run.state["y"][-1] - run.state["y"][0]) / 20.0
    assert mean_vy == pytest.approx(9.81 * 0.19866933 / 4.0, rel=0.05)
    assert abs(run.summary["max_abs_energy_drift"]) < 1e-8


def test_environment_variable_loads_systems_and_a_broken_file_is_one_line(tmp_path):
    broken = tmp_path / "broken_systems.py"
    broken.write_text("import nmkane_core\nraise RuntimeError('oops in my file')\n")
    env = {"NMKANE_SYSTEMS": os.pathsep.join([str(broken), str(SKATE)])}
    proc = nmkane("run", "skate-on-incline", "--t-final", "0.5", "--no-progress", env=env)
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if "broken_systems.py" in ln]
    assert len(lines) == 1 and "RuntimeError: oops in my file" in lines[0], proc.stderr
    assert "Traceback" not in proc.stderr


def test_a_broken_systems_option_is_the_commands_error_exit_2(tmp_path):
    broken = tmp_path / "typo.py"
    broken.write_text("from nmkane_core import System\nSystem(name='x', variants=None, parameters={'m': 1})\n")
    proc = nmkane("run", "x", "--systems", broken, "--no-progress")
    assert proc.returncode == 2 and "typo.py" in proc.stderr and "Traceback" not in proc.stderr
    missing = nmkane("run", "x", "--systems", tmp_path / "nope.py")
    assert missing.returncode == 2 and "no such file" in missing.stderr


def test_entry_point_group_adds_systems(monkeypatch):
    from importlib.metadata import EntryPoint

    from nmkane_core.run import plugins, registry

    ep = EntryPoint(name="pkg", value="tests._plugin_pkg:register_all", group=plugins.ENTRY_POINT_GROUP)
    monkeypatch.setattr(plugins, "entry_points", lambda group: [ep] if group == plugins.ENTRY_POINT_GROUP else [])
    monkeypatch.syspath_prepend(str(ROOT))
    errors = plugins._from_entry_points()
    assert errors == []
    assert "entry-point-skate" in registry.system_names()
    registry.unregister("entry-point-skate")


def test_rest_service_lists_and_runs_a_plugged_in_system(tmp_path):
    from fastapi.testclient import TestClient

    from backend import Settings, create_app
    from nmkane_core.run.plugins import load_systems

    assert load_systems([str(SKATE)]) == []
    with TestClient(create_app(Settings(db_path=tmp_path / "runs.sqlite3")), base_url="http://localhost") as client:
        names = [s["name"] for s in client.get("/api/systems").json()["systems"]]
        assert "skate-on-incline" in names
        r = client.post("/api/runs", json={"system": "skate-on-incline", "t_final": 0.5})
        assert r.status_code == 201, r.text
        doc = r.json()
        assert doc["summary"]["status"] == "ok" and set(doc["violation"]) == {"no_side_slip"}
        assert client.get(f"/api/runs/{doc['id']}").json()["system"] == "skate-on-incline"


def _write_model(path: Path, force: float) -> None:
    path.write_text(
        textwrap.dedent(f"""
        from nmkane_core import Parameter, System, register

        def model():
            import sympy as sp
            from nmkane_core import MechanicalModel, plain_symbols
            x, y = plain_symbols("x y"); u1, u2 = plain_symbols("u1 u2")
            m = sp.Symbol("m", positive=True)
            return MechanicalModel(q=(x, y), u=(u1, u2), params=(m,), C=sp.eye(2), D=sp.zeros(2, 1),
                                   Q=m * sp.eye(2), P=sp.Matrix([{force}, 0]),
                                   nonholonomic={{"guide": u2 - sp.tanh(u1)}}, u_independent=(u1,))

        register(System(name="pushed-bead", variants=model, parameters={{"m": Parameter(1.0, 0.0, 10.0)}},
                        default_initial={{"x": 0.0, "y": 0.0, "u1": 0.0}}, default_dt=0.01, default_t_final=1.0))
    """)
    )


def test_kernels_are_cached_by_model_no_sympy_later_and_never_stale(tmp_path):
    cache = tmp_path / "cache"
    env = {"NMKANE_CACHE_DIR": str(cache)}
    systems = tmp_path / "bead.py"
    probe = (
        "import sys, json\nfrom nmkane_core.run.plugins import load_systems\nfrom nmkane_core import simulate\n"
        f"assert load_systems([{str(systems)!r}]) == []\n"
        "r = simulate({'system': 'pushed-bead'})\n"
        "print(json.dumps({'x': float(r.state['x'][-1]), 'sympy': 'sympy' in sys.modules,"
        " 'tier': r.summary['kernel_tier']}))\n"
    )

    def run(cache_env=env):
        proc = subprocess.run(
            [sys.executable, "-c", probe],
            capture_output=True,
            text=True,
            timeout=600,
            env={**os.environ, **cache_env},
            cwd=ROOT,
        )
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout.strip().splitlines()[-1])

    _write_model(systems, 1.0)
    first = run()  # derives the kernel and compiles its C functions
    assert first["tier"] == "compiled" and first["sympy"] and first["x"] > 0
    again = run()  # a fresh process: from the cache, no sympy, compiled
    assert again == {"x": first["x"], "sympy": False, "tier": "compiled"}
    _write_model(systems, 2.0)  # the user edits the model: never the stale kernel
    changed = run()
    fresh = tmp_path / "fresh"  # the edited model made from scratch
    truth = run({**env, "NMKANE_CACHE_DIR": str(fresh)})
    assert changed["x"] == truth["x"] and changed["sympy"] and truth["sympy"]
    assert abs(changed["x"] - first["x"]) > 0.1 * first["x"]


def test_threads_asking_at_once_all_see_the_builtin_systems():
    """The first use registers the built-ins; a second thread asking meanwhile got an empty
    list (the web app then failed to build a browser's page: StopIteration)."""
    import subprocess
    import sys

    code = (
        "import threading\n"
        "from nmkane_core.run.registry import system_names\n"
        "out = []\n"
        "ts = [threading.Thread(target=lambda: out.append(len(system_names()))) for _ in range(8)]\n"
        "[t.start() for t in ts]; [t.join() for t in ts]\n"
        "print(out)\n"
        "assert min(out) > 0, out\n"
    )
    for _ in range(3):
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stdout + r.stderr[-500:]
