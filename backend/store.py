"""Runs in SQLite: one row per run, written in one transaction.

A run is inserted complete (settings, summary and the compressed result document) in a
single transaction before the service answers 201, in WAL mode with ``synchronous=FULL``:
after a crash or a kill there is never a half-written run, and every acknowledged run is
still there after a restart.
"""

from __future__ import annotations

import sqlite3
import threading
import time
import zlib
from pathlib import Path

import orjson

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id        TEXT PRIMARY KEY,
    created   REAL NOT NULL,
    system    TEXT NOT NULL,
    status    TEXT NOT NULL,
    settings  BLOB NOT NULL,
    summary   BLOB NOT NULL,
    document  BLOB NOT NULL
);
CREATE INDEX IF NOT EXISTS runs_created ON runs(created DESC);
"""


class RunStore:
    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._lock = threading.Lock()
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None)
        self._db.execute("PRAGMA journal_mode=WAL")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.executescript(SCHEMA)

    def add(self, run_id: str, system: str, status: str, settings: dict, summary: dict,
            document: bytes) -> float:
        created = time.time()
        row = (run_id, created, system, status, orjson.dumps(settings), orjson.dumps(summary),
               zlib.compress(document, 1))
        with self._lock:
            self._db.execute("BEGIN IMMEDIATE")
            try:
                self._db.execute("INSERT INTO runs VALUES (?, ?, ?, ?, ?, ?, ?)", row)
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
        return created

    def document(self, run_id: str) -> bytes | None:
        with self._lock:
            row = self._db.execute("SELECT document FROM runs WHERE id = ?", (run_id,)).fetchone()
        return None if row is None else zlib.decompress(row[0])

    def list(self, limit: int, offset: int) -> list[dict]:
        with self._lock:
            rows = self._db.execute(
                "SELECT id, created, system, status, settings, summary FROM runs "
                "ORDER BY created DESC LIMIT ? OFFSET ?", (limit, offset)).fetchall()
        return [{"id": r[0], "created": r[1], "system": r[2], "status": r[3],
                 "settings": orjson.loads(r[4]), "summary": orjson.loads(r[5])} for r in rows]

    def count(self) -> int:
        with self._lock:
            return self._db.execute("SELECT COUNT(*) FROM runs").fetchone()[0]

    def close(self) -> None:
        with self._lock:
            self._db.close()
            self._db = _Closed()


class _Closed:
    def execute(self, *a, **k):
        raise RuntimeError("the run store is closed")

    def close(self):
        pass
