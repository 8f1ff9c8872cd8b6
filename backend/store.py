"""Runs in SQLite: one row per run, written whole in one transaction.

A run is inserted complete — its settings and summary (for listings) and the run result
document exactly as it is served (JSON, zstd-compressed) — in a single transaction,
before the service answers 201.  The database is in WAL mode with ``synchronous=FULL``
(the commit is on disk before ``add`` returns): after a crash or a kill there is never a
half-written run, and every acknowledged run is still there after a restart.

One connection writes (behind a lock); each thread that reads gets its own read-only
connection, so fetches never wait for a commit.
"""

from __future__ import annotations

import sqlite3
import threading
import time
import zlib
from pathlib import Path

import orjson
import zstandard

__all__ = ["RunStore"]

SCHEMA = """
CREATE TABLE IF NOT EXISTS runs (
    id        TEXT PRIMARY KEY,
    created   REAL NOT NULL,          -- Unix time, s
    system    TEXT NOT NULL,
    status    TEXT NOT NULL,
    settings  BLOB NOT NULL,          -- JSON: the resolved settings
    summary   BLOB NOT NULL,          -- JSON: the run summary
    document  BLOB NOT NULL           -- the run result document (JSON), zstd-compressed
);
CREATE INDEX IF NOT EXISTS runs_created ON runs(created DESC);
"""

_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
_ZSTD_LEVEL = 1        # 570 kB of JSON -> 210 kB in ~1 ms (zlib level 1: 226 kB in ~6 ms)


class RunStore:
    """The run table of one SQLite file."""

    def __init__(self, path: Path):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._write_lock = threading.Lock()
        self._db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
        mode = self._db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
        if mode.lower() != "wal":
            raise RuntimeError(f"{self.path}: SQLite could not switch to WAL mode (got {mode!r})")
        self._db.execute("PRAGMA synchronous=FULL")
        self._db.executescript(SCHEMA)
        self._local = threading.local()
        self._readers: list[sqlite3.Connection] = []
        self._readers_lock = threading.Lock()
        self._closed = False

    # -- codec (compressor objects are not thread-safe: one per thread) ---------------
    def _codec(self):
        c = getattr(self._local, "codec", None)
        if c is None:
            c = self._local.codec = (zstandard.ZstdCompressor(level=_ZSTD_LEVEL), zstandard.ZstdDecompressor())
        return c

    def _decode(self, blob: bytes) -> bytes:
        if blob[:4] == _ZSTD_MAGIC:
            return self._codec()[1].decompress(blob)
        return zlib.decompress(blob)              # rows written before zstd was used

    # -- connections ----------------------------------------------------------------
    def _reader(self) -> sqlite3.Connection:
        if self._closed:
            raise RuntimeError("the run store is closed")
        con = getattr(self._local, "reader", None)
        if con is None:
            con = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
            con.execute("PRAGMA query_only=ON")
            self._local.reader = con
            with self._readers_lock:
                self._readers.append(con)
        return con

    # -- writing --------------------------------------------------------------------
    def record(self, run_id: str, system: str, status: str, settings: dict, summary: dict,
               document: bytes) -> tuple:
        """A run as a row, ready for :meth:`insert` (the CPU work: encoding, compression)."""
        return (run_id, system, status, orjson.dumps(settings), orjson.dumps(summary),
                self._codec()[0].compress(document))

    def add(self, run_id: str, system: str, status: str, settings: dict, summary: dict,
            document: bytes) -> float:
        """Store one run in one transaction; returns its creation time (Unix s)."""
        return self.insert(self.record(run_id, system, status, settings, summary, document))

    def insert(self, record: tuple) -> float:
        """Write one run (a :meth:`record`) in one transaction, on disk when this returns."""
        run_id, system, status, settings, summary, blob = record
        created = time.time()
        row = (run_id, created, system, status, settings, summary, blob)
        with self._write_lock:
            if self._closed:
                raise RuntimeError("the run store is closed")
            self._db.execute("BEGIN IMMEDIATE")
            try:
                self._db.execute("INSERT INTO runs (id, created, system, status, settings, summary, document) "
                                 "VALUES (?, ?, ?, ?, ?, ?, ?)", row)
                self._db.execute("COMMIT")
            except BaseException:
                self._db.execute("ROLLBACK")
                raise
        return created

    # -- reading --------------------------------------------------------------------
    def document(self, run_id: str) -> bytes | None:
        """The run result document (JSON bytes) as it was served, or None."""
        row = self._reader().execute("SELECT document FROM runs WHERE id = ?", (run_id,)).fetchone()
        return None if row is None else self._decode(row[0])

    def list(self, limit: int, offset: int, system: str | None = None, status: str | None = None) -> list[dict]:
        """Newest first: id, created, system, status, settings, summary."""
        where, args = self._where(system, status)
        rows = self._reader().execute(
            f"SELECT id, created, system, status, settings, summary FROM runs{where} "
            "ORDER BY created DESC, rowid DESC LIMIT ? OFFSET ?", (*args, limit, offset)).fetchall()
        return [{"id": r[0], "created": r[1], "system": r[2], "status": r[3],
                 "settings": orjson.loads(r[4]), "summary": orjson.loads(r[5])} for r in rows]

    def count(self, system: str | None = None, status: str | None = None) -> int:
        where, args = self._where(system, status)
        return self._reader().execute(f"SELECT COUNT(*) FROM runs{where}", args).fetchone()[0]

    @staticmethod
    def _where(system, status):
        cond, args = [], []
        if system is not None:
            cond.append("system = ?")
            args.append(system)
        if status is not None:
            cond.append("status = ?")
            args.append(status)
        return (" WHERE " + " AND ".join(cond) if cond else ""), tuple(args)

    def close(self) -> None:
        with self._write_lock:
            if self._closed:
                return
            self._closed = True
            self._db.close()
        with self._readers_lock:
            for con in self._readers:
                con.close()
            self._readers.clear()
