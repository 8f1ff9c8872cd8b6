"""Every registered system runs with no options (issue 42, item 3): the library, the CLI's ``run``
and ``export``, and REST with only ``{"system": NAME}`` — the benchmark's own A01 (2000 s at
Δt = 1e-3: 2,000,000 steps) included, whose output keeps within the row cap by itself and says so.
The repository's example systems too (the 81-rod chain has its own test module)."""

import tempfile
from pathlib import Path

import pytest

from nmkane_core import simulate
from nmkane_core.cli import main
from nmkane_core.run.registry import system_names
from tests._helpers import require

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = {"isokinetic-bowl": "isokinetic_bowl.py", "skate-on-incline": "skate_on_incline.py"}


@pytest.mark.parametrize("name", system_names())
def test_every_catalogue_system_runs_and_exports_with_no_options(name, tmp_path, capsys):
    run = simulate({"system": name}, progress=False)
    assert run.status == "ok", run.summary["message"]
    assert main(["run", name, "--no-progress"]) == 0
    assert "status   ok" in capsys.readouterr().out
    out = tmp_path / f"{name}.html"
    assert main(["export", name, "--out", str(out)]) == 0
    assert out.stat().st_size > 10_000


def test_a_run_longer_than_the_row_cap_thins_its_output_and_says_so():
    run = simulate({"system": "iftomm-a01"}, progress=False)  # 2,000,000 steps, 2,000,000 rows at most
    assert run.settings["every"] == 2 and len(run.t) == 1_000_001
    assert any(w.startswith("every = 2: one output row every 2 steps") for w in run.summary["warnings"])
    given = simulate({"system": "iftomm-a02", "every": 7}, progress=False)  # given: as given, nothing said
    assert given.settings["every"] == 7 and not any("every" in w for w in given.summary["warnings"])


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_the_example_systems_run_with_no_options(name, capsys):
    path = ROOT / "examples" / EXAMPLES[name]
    assert main(["run", name, "--systems", str(path), "--no-progress"]) == 0
    assert "status   ok" in capsys.readouterr().out


def test_every_catalogue_system_runs_through_rest_with_only_its_name():
    require("fastapi")
    from fastapi.testclient import TestClient

    from backend.app import create_app
    from backend.config import Settings

    with (
        tempfile.TemporaryDirectory() as tmp,
        TestClient(create_app(Settings(data_dir=tmp, warm_kernels=False)), base_url="http://localhost") as c,
    ):
        for name in system_names():
            r = c.post("/api/runs", json={"system": name})
            assert r.status_code == 201, (name, r.text[:300])
            doc = c.get(f"/api/runs/{r.json()['id']}").json()
            assert doc["summary"]["status"] == "ok", (name, doc["summary"]["message"])
            assert len(doc["t"]) <= 100_001  # the service's own row cap (a run keeps within it by itself)
