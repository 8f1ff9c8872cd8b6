"""The service's settings: one class (pydantic-settings) that alone reads the environment,
refuses every bad value the same way (naming the variable or the field, the value and what is
allowed), and whose field descriptions are what GET /api/systems serves."""

import re
from pathlib import Path

import pytest
from fastapi.testclient import TestClient

from backend import Settings, create_app
from backend.config import LIMIT_DESCRIPTIONS, env_name, settings_table
from nmkane_core.errors import InputError

BACKEND = Path(__file__).resolve().parents[2] / "backend"
ENV_READ = re.compile(r"\bos\.environ\b|\bgetenv\s*\(|from\s+os\s+import\s+[^\n]*\b(environ|getenv)\b")


def test_the_environment_is_read_only_in_backend_config():
    readers = sorted(
        f"{path.relative_to(BACKEND.parent)}:{n}"
        for path in BACKEND.rglob("*.py")
        if path.name != "config.py" or path.parent != BACKEND
        for n, line in enumerate(path.read_text().splitlines(), 1)
        if ENV_READ.search(line)
    )
    assert not readers, "read the environment in backend/config.py (a Settings field) instead:\n" + "\n".join(readers)


def test_the_scan_finds_a_reader():  # the test above can fail
    assert ENV_READ.search('x = os.environ.get("NMKANE_MAX_SWEEP_RUNS")')
    assert ENV_READ.search("limit = getenv('NMKANE_MAX_SWEEP_RUNS')")
    assert ENV_READ.search("from os import getenv, path")
    assert not ENV_READ.search("settings.max_sweep_runs")


def test_a_bad_max_sweep_runs_is_refused_naming_the_variable_like_queue_limit(monkeypatch):
    monkeypatch.setenv("NMKANE_MAX_SWEEP_RUNS", "abc")
    with pytest.raises(InputError) as sweep:
        Settings()
    monkeypatch.delenv("NMKANE_MAX_SWEEP_RUNS")
    monkeypatch.setenv("NMKANE_QUEUE_LIMIT", "abc")
    with pytest.raises(InputError) as queue:
        Settings()
    assert (
        str(sweep.value)
        == "environment variable NMKANE_MAX_SWEEP_RUNS: got 'abc' (not an integer); allowed: an integer ≥ 1"
    )
    assert (
        str(queue.value)
        == "environment variable NMKANE_QUEUE_LIMIT: got 'abc' (not an integer); allowed: an integer ≥ 0"
    )


@pytest.mark.parametrize(
    "variable, value, allowed",
    [
        ("NMKANE_MAX_CONCURRENT_RUNS", "0", "an integer ≥ 1"),
        ("NMKANE_MAX_STEPS", "1e6", "an integer ≥ 1"),
        ("NMKANE_MAX_ROWS", "1", "an integer ≥ 2"),
        ("NMKANE_MAX_REQUEST_BYTES", "-5", "an integer ≥ 1"),
        ("NMKANE_MAX_WALL_TIME_S", "inf", "a finite number > 0"),
        ("NMKANE_READ_TIMEOUT_S", "0", "a finite number > 0"),
        ("NMKANE_MAX_STORED_RUNS", "lots", "an integer ≥ 1"),
        ("NMKANE_MAX_STORE_MB", "0", "an integer ≥ 1 (megabytes)"),
        ("NMKANE_STORE_FULL", "delete-everything", "one of refuse, evict-oldest"),
        ("NMKANE_CORS_ORIGINS", "*", "origins"),
        ("NMKANE_DASK_SCHEDULER", "scheduler.lab:8786", "tcp://HOST:PORT"),
        ("NMKANE_WARM_KERNELS", "perhaps", "true or false"),
    ],
)
def test_every_bad_environment_value_names_the_variable_the_value_and_what_is_allowed(
    monkeypatch, variable, value, allowed
):
    monkeypatch.setenv(variable, value)
    with pytest.raises(InputError) as err:
        Settings()
    text = str(err.value)
    assert text.startswith(f"environment variable {variable}: got {value!r}") and f"allowed: {allowed}" in text


def test_a_bad_token_is_refused_without_showing_it(monkeypatch):
    monkeypatch.setenv("NMKANE_TOKEN", "short-secret")
    with pytest.raises(InputError, match="NMKANE_TOKEN") as err:
        Settings()
    assert "short-secret" not in str(err.value) and "at least 16 characters" in str(err.value)


def test_several_bad_values_are_named_at_once(monkeypatch):
    monkeypatch.setenv("NMKANE_MAX_ROWS", "lots")
    with pytest.raises(InputError) as err:
        Settings(max_concurrent_runs=0)
    assert [e.field for e in err.value.errors] == [
        "Settings.max_concurrent_runs",
        "environment variable NMKANE_MAX_ROWS",
    ]
    assert "(2 problems)" in str(err.value)


def test_a_value_given_directly_is_named_as_a_field_and_wins_over_the_environment(monkeypatch):
    monkeypatch.setenv("NMKANE_MAX_ROWS", "lots")
    assert Settings(max_rows=500).max_rows == 500  # the environment's bad value is not used
    with pytest.raises(InputError, match=r"^Settings\.max_rows: got True \(true/false is not a number\)"):
        Settings(max_rows=True)
    monkeypatch.delenv("NMKANE_MAX_ROWS")
    with pytest.raises(InputError, match=r"^Settings\.max_row: got 5 \(unknown\); allowed: one of data_dir, "):
        Settings(max_row=5)


def test_store_megabytes_from_the_environment_are_bytes_in_the_settings(monkeypatch):
    monkeypatch.setenv("NMKANE_MAX_STORE_MB", "5")
    assert Settings().max_store_bytes == 5_000_000
    assert Settings(max_store_bytes=30_000).max_store_bytes == 30_000
    monkeypatch.delenv("NMKANE_MAX_STORE_MB")
    assert Settings().max_store_bytes == 2_000_000_000


def test_blank_values_are_the_defaults_and_lists_are_comma_separated(monkeypatch):
    monkeypatch.setenv("NMKANE_MAX_ROWS", "  ")
    monkeypatch.setenv("NMKANE_QUEUE_LIMIT", "")
    monkeypatch.setenv("NMKANE_ALLOWED_HOSTS", "Lab.Example, ,class.example")
    monkeypatch.setenv("NMKANE_DASK_SCHEDULER", "tcp://127.0.0.1:8786")
    monkeypatch.setenv("NMKANE_MAX_SWEEP_RUNS", "12")
    s = Settings()
    assert (s.max_rows, s.queue_limit) == (100_000, 64)
    assert s.allowed_hosts == ("lab.example", "class.example")
    assert (s.dask_scheduler, s.max_sweep_runs) == ("tcp://127.0.0.1:8786", 12)


def test_limits_and_their_descriptions_come_from_the_fields():
    fields = Settings.model_fields
    assert all(info.description for info in fields.values()), "every setting says what it is"
    assert list(LIMIT_DESCRIPTIONS) == list(Settings(warm_kernels=False).limits())
    assert all(LIMIT_DESCRIPTIONS[name] == fields[name].description for name in LIMIT_DESCRIPTIONS)
    table = settings_table()
    assert all(f"`{env_name(name)}`" in table for name in fields)
    assert env_name("db_path") == "NMKANE_DB" and env_name("max_store_bytes") == "NMKANE_MAX_STORE_MB"


def test_the_sweep_limit_is_a_setting_of_the_app(tmp_path):
    s = Settings(data_dir=tmp_path, warm_kernels=False, max_sweep_runs=3)
    with TestClient(create_app(s), base_url="http://localhost") as c:
        body = {"settings": {"system": "sliding-particle", "t_final": 0.2}, "grid": ["gamma1=-1,-2,-3,-4"]}
        r = c.post("/api/sweeps", json=body)
        assert r.status_code == 422 and "at most 3 runs" in r.json()["detail"][0]["msg"], r.text


def test_wrong_methods_on_every_router_list_the_allowed_ones(tmp_path):
    with TestClient(create_app(Settings(data_dir=tmp_path, warm_kernels=False)), base_url="http://localhost") as c:
        for method, path, allowed in (
            ("PUT", "/api/sweeps", "POST"),
            ("DELETE", "/api/sweeps/some-id", "GET"),
            ("DELETE", "/api/runs", "GET, POST"),
            ("POST", "/api/health", "GET"),
        ):
            r = c.request(method, path)
            assert r.status_code == 405 and r.headers["allow"] == allowed, (method, path, r.headers)
            assert r.json()["detail"][0]["allowed"] == allowed


def test_nmkane_serve_with_a_bad_variable_says_so_in_one_line(monkeypatch, capsys):
    import nmkane_core.cli.commands as commands
    from backend.cli import SERVE
    from nmkane_core.cli import main

    monkeypatch.setenv("NMKANE_MAX_SWEEP_RUNS", "abc")
    monkeypatch.setattr(commands, "contributed", lambda: [SERVE])  # the entry point, faked
    commands.all_commands.cache_clear()
    try:
        assert main(["serve", "--no-web", "--api-port", "0"]) == 2
    finally:
        commands.all_commands.cache_clear()
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "NMKANE_MAX_SWEEP_RUNS" in err and "'abc'" in err, err
