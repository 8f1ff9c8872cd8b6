"""Issue 44, items 5 and 8: the run store under disk and file faults.

A full disk answers 507 naming the store and what to do, and deleting still works; SQLite's own
rollback is not repeated; a store that cannot be written, a folder in the file's place or a
damaged file is refused at start (``nmkane serve``, ``nmkane store``) in one line naming the
file and how to recover.

A full disk is made with ``PRAGMA max_page_count`` (SQLite answers SQLITE_FULL, "database or
disk is full", as on a full disk) or by making the store see no free space (``shutil.disk_usage``);
a read-only store with a ``mode=ro`` connection (the tests run as root, which ignores file
permissions).  A real 2 MB filesystem was measured by hand (docs/reliability.md).
"""

import logging
import os
import shutil
import sqlite3
import types

import pytest
from fastapi.testclient import TestClient

import backend.serve as serve_module
import backend.store as store_module
from backend import Settings, create_app
from backend.errors import ErrorResponse
from backend.store import (
    RESERVE_BYTES,
    RunStore,
    StoreCorrupt,
    StoreDiskFull,
    StoreReadOnly,
    StoreUnavailable,
    store_fault,
)
from backend.sweep_store import SweepStore

SMALL = {"system": "appell-hamel", "model": "nonlinear", "dt": 0.01, "t_final": 2}


def _client(settings):
    return TestClient(create_app(settings), base_url="http://localhost", raise_server_exceptions=False)


def _error(r, status):
    assert r.status_code == status, r.text[:500]
    ErrorResponse.model_validate(r.json())
    return r.json()["detail"][0]


def _no_growth(db: sqlite3.Connection) -> None:
    """The file may not grow past its pages now: SQLITE_FULL, as on a full disk."""
    pages = db.execute("PRAGMA page_count").fetchone()[0]
    db.execute(f"PRAGMA max_page_count = {pages}")


def _store(tmp_path, runs=3, size=20_000, name="runs.sqlite3"):
    store = RunStore(tmp_path / name)
    for i in range(runs):
        store.insert((f"r{i}", "s", "ok", b"{}", b"{}", os.urandom(size)))
    return store


# ------------------------------------------------------------------------------ a full disk
def test_a_full_disk_answers_507_naming_the_store_and_deleting_makes_room(tmp_path, caplog):
    settings = Settings(data_dir=tmp_path, warm_kernels=False)
    with _client(settings) as c, caplog.at_level(logging.DEBUG):
        ids = [c.post("/api/runs", json=SMALL).json()["id"] for _ in range(2)]
        _no_growth(c.app.state.service.store._db)
        it = _error(c.post("/api/runs", json=SMALL), 507)
        assert it["type"] == "disk_full" and str(settings.database) in it["msg"]
        for what in ("free disk space", "delete runs", "DELETE /api/runs/{id}", "nmkane store prune"):
            assert what in it["allowed"] and what in it["msg"], what
        assert c.get("/api/health").status_code == 200  # reads and deletes still work
        assert [c.delete(f"/api/runs/{i}").status_code for i in ids] == [204, 204]
        assert c.post("/api/runs", json=SMALL).status_code == 201  # in the pages of the deleted runs
    assert "cannot rollback" not in caplog.text and "internal_error" not in caplog.text


def test_a_full_disk_answers_507_to_a_new_sweep(tmp_path):
    settings = Settings(data_dir=tmp_path, warm_kernels=False)
    values = ",".join(f"{-1.123456789 - i}" for i in range(1000))  # a request of some 20 kB to store
    with _client(settings) as c:
        _no_growth(c.app.state.sweeps.store._db)
        r = c.post("/api/sweeps", json={"settings": {"system": "sliding-particle"}, "grid": [f"gamma1={values}"]})
        it = _error(r, 507)
        assert it["type"] == "disk_full" and str(settings.database) in it["msg"] and "free disk space" in it["msg"]


def test_sqlites_own_rollback_is_not_repeated(tmp_path, caplog):
    caplog.set_level(logging.DEBUG)
    store = _store(tmp_path)
    _no_growth(store._db)
    with pytest.raises(StoreDiskFull, match="disk is full"):
        store.insert(("big", "s", "ok", b"{}", b"{}", os.urandom(200_000)))
    assert not store._db.in_transaction and store.count() == 3
    sweeps = SweepStore(tmp_path / "runs.sqlite3")
    sweeps.create("w", "s", 10, {}, ["x"])
    _no_growth(sweeps._db)
    with pytest.raises(StoreDiskFull, match=r"runs\.sqlite3"):
        sweeps.add_rows("w", 0, [{"x": "y" * 50_000}])
    assert not sweeps._db.in_transaction and sweeps.get("w")["done"] == 0
    assert "rollback" not in caplog.text
    store.close()


def _small_disk(monkeypatch, folder, size):
    """``folder`` seen as a disk of ``size`` bytes (its files' blocks are what is used); returns
    how much they use.  SQLite still writes to the real disk: this checks the store's accounts."""

    def used():
        return sum(p.stat().st_blocks * 512 for p in folder.iterdir() if p.is_file())

    monkeypatch.setattr(shutil, "disk_usage", lambda f: types.SimpleNamespace(free=max(0, size - used())))
    return used


def test_a_run_the_disk_cannot_take_is_refused_before_anything_is_written(tmp_path, monkeypatch):
    used = _small_disk(monkeypatch, tmp_path, 1_500_000)
    store, stored = RunStore(tmp_path / "runs.sqlite3"), 0
    with pytest.raises(StoreDiskFull, match=r"\d+ kB free on its disk, \d+ kB needed") as e:
        for i in range(100):
            store.insert((f"r{i}", "s", "ok", b"{}", b"{}", os.urandom(60_000)))
            stored += 1
            assert used() <= 1_500_000  # never more than the disk: SQLite could always have written
    assert e.value.status == 507 and store.count() == stored > 5
    assert store.delete("r0") and store.delete("r1")  # deletes need no room on the disk
    store.insert(("new", "s", "ok", b"{}", b"{}", os.urandom(60_000)))  # in the pages of deleted runs
    assert store.count() == stored - 1 and used() <= 1_500_000
    store.close()


class _FullOnce:
    """The store's connection whose first DELETE meets a full disk."""

    def __init__(self, db):
        self.db, self.failed = db, False

    def __getattr__(self, name):
        return getattr(self.db, name)

    def execute(self, sql, *args):
        if sql.startswith("DELETE") and not self.failed:
            self.failed = True
            raise sqlite3.OperationalError("database or disk is full")
        return self.db.execute(sql, *args)


def test_a_delete_on_a_full_disk_releases_the_reserve_and_succeeds(tmp_path, caplog):
    store = _store(tmp_path)
    store._db = _FullOnce(store._db)
    with caplog.at_level(logging.WARNING):
        assert store.delete("r1")
    assert store._db.failed and "its reserve was released for a delete" in caplog.text
    assert store.count() == 2
    assert (tmp_path / "runs.sqlite3-reserve").stat().st_size == RESERVE_BYTES  # held again: there is room
    store._db = store._db.db
    store.close()


# -------------------------------------------------------------------- what each fault says
@pytest.mark.parametrize(
    "message, kind, words",
    [
        ("database or disk is full", StoreDiskFull, ["disk is full", "delete runs", "nmkane store prune"]),
        ("attempt to write a readonly database", StoreReadOnly, ["cannot be written", "writable", "NMKANE_DB"]),
        ("file is not a database", StoreCorrupt, ["move the file aside", ".recover"]),
        ("database disk image is malformed", StoreCorrupt, ["truncated", "runs.sqlite3-wal"]),
        ("unable to open database file", StoreUnavailable, ["cannot be opened", "NMKANE_DB"]),
        ("database is locked", StoreUnavailable, ["locked"]),
    ],
)
def test_each_sqlite_fault_names_the_file_and_what_to_do(tmp_path, message, kind, words):
    fault = store_fault(sqlite3.OperationalError(message), tmp_path / "runs.sqlite3")
    assert type(fault) is kind and str(fault).startswith(f"{tmp_path / 'runs.sqlite3'}: ")
    assert "\n" not in str(fault) and message in str(fault)
    assert all(w in str(fault) for w in words), str(fault)
    assert fault.status == (507 if kind is StoreDiskFull else 503)
    assert store_fault(sqlite3.IntegrityError("UNIQUE constraint failed: runs.id"), tmp_path) is None  # a bug stays one


# ------------------------------------------------------------------------ read-only stores
def _read_only(monkeypatch):
    """The store's file opened read-only, as for a file this user may not write (root may)."""

    def connect(path, **kw):
        return sqlite3.connect(f"file:{path}?mode=ro", uri=True, **kw)

    monkeypatch.setattr(store_module, "sqlite3", types.SimpleNamespace(**{**vars(sqlite3), "connect": connect}))


def test_a_read_only_store_is_refused_when_opened_and_still_readable(tmp_path, monkeypatch):
    _store(tmp_path).close()
    _read_only(monkeypatch)
    with pytest.raises(StoreReadOnly, match=r"runs\.sqlite3: the run store cannot be written") as e:
        RunStore(tmp_path / "runs.sqlite3")
    assert "\n" not in str(e.value) and "writable" in str(e.value)
    reading = RunStore(tmp_path / "runs.sqlite3", writable=False)  # `nmkane store info`
    assert reading.count() == 3
    reading.close()


def test_a_store_that_stops_taking_writes_answers_503_and_health_says_so(tmp_path):
    settings = Settings(data_dir=tmp_path, warm_kernels=False)
    with _client(settings) as c:
        assert c.post("/api/runs", json=SMALL).status_code == 201
        store = c.app.state.service.store
        writer = store._db  # the filesystem goes read-only under the service
        store._db = sqlite3.connect(
            f"file:{settings.database}?mode=ro", uri=True, isolation_level=None, check_same_thread=False
        )
        it = _error(c.post("/api/runs", json=SMALL), 503)
        assert it["type"] == "store_read_only" and str(settings.database) in it["msg"]
        assert _error(c.get("/api/health"), 503)["type"] == "store_read_only"
        assert c.get("/api/runs").json()["total"] == 1  # reads go on
        store._db.close()
        store._db = writer  # writable again: health is well again
        assert c.get("/api/health").status_code == 200


# --------------------------------------------------------- start-up: serve and nmkane store
@pytest.fixture()
def nmkane(monkeypatch, capsys):
    """``nmkane ARGS...`` in this process: (exit code, stderr); the API must never start."""
    import nmkane_core.cli.commands as commands
    from backend.cli import SERVE, STORE
    from nmkane_core.cli import main

    def api_started(*args, **kw):
        raise AssertionError("the store should have been refused before the REST API starts")

    monkeypatch.setattr(serve_module, "_start_api", api_started)
    monkeypatch.setattr(commands, "contributed", lambda: [SERVE, STORE])
    commands.all_commands.cache_clear()

    def run(*argv):
        code = main(list(argv))
        return code, capsys.readouterr().err

    yield run
    commands.all_commands.cache_clear()


def _bad_stores(tmp_path):
    good = _store(tmp_path, runs=20, size=50_000, name="good.sqlite3")
    good.close()
    whole = (tmp_path / "good.sqlite3").read_bytes()
    (tmp_path / "folder.sqlite3").mkdir()
    (tmp_path / "truncated.sqlite3").write_bytes(whole[: len(whole) // 2])
    (tmp_path / "garbage.sqlite3").write_bytes(b"not a database at all\n" * 100)
    return {
        "folder": ["is a directory, not a run store", "remove or rename it"],
        "truncated": ["damaged, truncated", "move the file aside", "start again", ".recover"],
        "garbage": ["not an SQLite file", "move the file aside", ".recover"],
    }


def test_a_bad_store_refuses_nmkane_serve_in_one_line_naming_the_file(tmp_path, monkeypatch, nmkane):
    for name, words in _bad_stores(tmp_path).items():
        path = tmp_path / f"{name}.sqlite3"
        monkeypatch.setenv("NMKANE_DB", str(path))
        code, err = nmkane("serve", "--no-web", "--api-port", "0")
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert err.startswith(f"nmkane serve: error: {path}: ") and "port" not in err
        assert all(w in err for w in words), err


def test_a_read_only_store_refuses_nmkane_serve(tmp_path, monkeypatch, nmkane):
    _store(tmp_path).close()
    _read_only(monkeypatch)
    monkeypatch.setenv("NMKANE_DB", str(tmp_path / "runs.sqlite3"))
    code, err = nmkane("serve", "--no-web", "--api-port", "0")
    assert code == 2 and err.count("\n") == 1 and "cannot be written" in err, err


def test_nmkane_store_on_a_bad_store_says_how_to_recover(tmp_path, nmkane):
    for name, words in _bad_stores(tmp_path).items():
        path = tmp_path / f"{name}.sqlite3"
        for action in ("info", "check"):
            code, err = nmkane("store", "--db", str(path), action)
            assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
            assert err.startswith(f"nmkane store: error: {path}: ") and all(w in err for w in words), err
    assert nmkane("store", "--db", str(tmp_path / "good.sqlite3"), "check") == (0, "")


def test_nmkane_store_check_finds_damage_inside_a_store_that_opens(tmp_path, nmkane, capsys):
    _store(tmp_path, runs=30, size=30_000).close()
    path = tmp_path / "runs.sqlite3"
    with sqlite3.connect(path) as db:
        root = db.execute("SELECT rootpage FROM sqlite_master WHERE name = 'runs_created'").fetchone()[0]
    with open(path, "r+b") as f:  # the index's root page overwritten: the table itself still reads
        f.seek((root - 1) * 4096)
        f.write(b"\x0d" + os.urandom(4095))
    code, err = nmkane("store", "--db", str(path), "check")
    assert code == 2 and "damaged" in err and "move the file aside" in err, err
