"""Runs in SQLite: one row per run, written whole in one transaction.

A run is inserted complete — its settings and summary (for listings) and the run result
document exactly as it is served (JSON, zstd-compressed) — in a single transaction,
before the service answers 201.  The database is in WAL mode with ``synchronous=FULL``
(the commit is on disk before ``add`` returns): after a crash or a kill there is never a
half-written run, and every acknowledged run is still there after a restart.

One connection writes (behind a lock); each thread that reads gets its own read-only
connection, so fetches never wait for a commit.

The store has a cap (:class:`StoreCap`): ``max_runs`` runs, ``max_bytes`` bytes of stored rows
(settings, summary, the compressed document; the sweeps' rows count too).  A new run past it:
``refuse`` (the default) raises :class:`StoreFull`, nothing stored is touched; ``evict-oldest``
deletes the oldest runs, in the insert's transaction, until it fits.  Runs are deleted with
:meth:`RunStore.delete` and :meth:`RunStore.prune` (SQLite reuses the pages; ``VACUUM`` shrinks).

Faults of the file and the disk (:mod:`backend.store_disk`) become a :class:`StoreError` naming
the file and what to do: one line in the CLI; from the service 507 for a full disk, 503 otherwise.
A store that cannot be opened read-write is refused when it is opened (a write that changes
nothing is tried then).  After an error SQLite may have rolled the transaction back itself; the
store rolls back only one still open.  On a full disk a new run is refused before anything is
written, and deleting still works: a delete does not overwrite the freed pages with zeros
(``secure_delete=FAST``; Debian's SQLite zeroes them by default, so deleting a run wrote as much
as the run), one that meets a full disk releases the store's reserve and tries again, and
:meth:`RunStore.prune` deletes in transactions of a few hundred runs.  New runs reuse the pages
of deleted ones.
"""

from __future__ import annotations

import contextlib
import logging
import sqlite3
import threading
import time
import zlib
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import orjson
import zstandard

from .store_disk import (
    RESERVE_BYTES,
    DiskRoom,
    StoreCorrupt,
    StoreDiskFull,
    StoreError,
    StoreReadOnly,
    StoreUnavailable,
    cannot_open,
    corrupt,
    store_fault,
)

__all__ = [
    "POLICIES",
    "RESERVE_BYTES",
    "RunStore",
    "StoreCap",
    "StoreFull",
    "StoreError",
    "StoreDiskFull",
    "StoreReadOnly",
    "StoreCorrupt",
    "StoreUnavailable",
    "store_fault",
]

log = logging.getLogger("nmkane.backend")
_T = TypeVar("_T")

#: what a full store does with a new run
POLICIES = ("refuse", "evict-oldest")


class StoreFull(Exception):
    """The store is at its cap and its policy is ``refuse``."""

    def __init__(self, cap: StoreCap, count: int, size: int, need: int = 0):
        self.cap, self.count, self.size, self.need = cap, count, size, need
        super().__init__(
            f"the run store is full ({count:,} of at most {cap.max_runs:,} runs, "
            f"{size / 1e6:,.1f} of at most {cap.max_bytes / 1e6:,.1f} MB); it keeps every stored run "
            f"(policy {cap.policy!r}): delete runs (DELETE /api/runs/{{id}}, `nmkane store prune`) "
            "or raise the cap"
        )


class StoreCap:
    """The store's cap: ``max_runs`` runs, ``max_bytes`` bytes of rows, and the ``policy`` when a
    new run would pass it (one of :data:`POLICIES`)."""

    def __init__(self, max_runs: int, max_bytes: int, policy: str = "refuse"):
        if policy not in POLICIES:
            raise ValueError(f"store policy {policy!r}: one of {', '.join(POLICIES)}")
        self.max_runs, self.max_bytes, self.policy = int(max_runs), int(max_bytes), policy


UNCAPPED = StoreCap(2**62, 2**62)

_PRUNE_BATCH = 200  # runs deleted per transaction by prune (the log is reused between them)


_ROW_BYTES = "length(settings) + length(summary) + length(document)"

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

#: a write that changes nothing: a read-only store refuses it (BEGIN IMMEDIATE alone it does not)
_PROBE = "DELETE FROM runs WHERE 0"

_ZSTD_MAGIC = b"\x28\xb5\x2f\xfd"
_ZSTD_LEVEL = 1  # 570 kB of JSON -> 210 kB in ~1 ms (zlib level 1: 226 kB in ~6 ms)


class RunStore:
    """The run table of one SQLite file.

    ``writable=False`` (reading only, e.g. ``nmkane store info``): no write is tried at
    opening and no reserve is made; otherwise a store that cannot be written is refused."""

    def __init__(self, path: Path, cap: StoreCap | None = None, *, writable: bool = True):
        self.path = Path(path)
        self.cap = cap if cap is not None else UNCAPPED
        #: the fault of the last write, None after a write that succeeded (``/api/health``)
        self.fault: StoreError | None = None
        self._write_lock = threading.Lock()
        self._local = threading.local()
        self._readers: list[sqlite3.Connection] = []
        self._readers_lock = threading.Lock()
        self._closed = False
        self._disk = DiskRoom(self.path)
        try:
            self._db = self._open(writable)
        except StoreDiskFull:  # no room even for SQLite's index of the log: what the reserve is for
            if not self._disk.release_reserve():
                raise
            log.warning("%s: the disk is full; its reserve was released to open it", self.path)
            self._db = self._open(writable)
        self._disk.page = self._db.execute("PRAGMA page_size").fetchone()[0]
        if writable:
            self._disk.keep_reserve()

    def _open(self, writable: bool) -> sqlite3.Connection:
        """The writer connection, set up; one :class:`StoreError` line for whatever fails."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise cannot_open(self.path, f"its directory cannot be made ({e.strerror})") from e
        db = None
        try:
            db = sqlite3.connect(self.path, check_same_thread=False, isolation_level=None, timeout=30)
            mode = db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise StoreUnavailable(
                    self.path, f"SQLite could not switch it to WAL mode (got {mode!r})", "put it on a local disk"
                )
            db.execute("PRAGMA synchronous=FULL")
            db.execute("PRAGMA secure_delete=FAST")  # a delete writes a few pages, not the run in zeros
            db.executescript(SCHEMA)
            if writable:  # refused now rather than at the first run
                db.execute("BEGIN IMMEDIATE")
                try:
                    db.execute(_PROBE)
                finally:
                    db.execute("ROLLBACK")
            self._count, self._bytes = db.execute(
                f"SELECT COUNT(*), COALESCE(SUM({_ROW_BYTES}), 0) FROM runs"
            ).fetchone()
            return db
        except (sqlite3.Error, StoreError) as e:
            if db is not None:
                db.close()
            if isinstance(e, StoreError):
                raise
            raise (store_fault(e, self.path) or cannot_open(self.path, "the run store cannot be opened", str(e))) from e

    # -- the cap --------------------------------------------------------------------
    @property
    def size(self) -> int:
        """Bytes of the stored rows (what the cap counts)."""
        return self._bytes

    def check_room(self) -> None:
        """Raise :class:`StoreFull` when a new run would be refused now (checked before a run
        starts, so a full store answers at once; the insert checks again)."""
        if self.cap.policy == "refuse" and (self._count >= self.cap.max_runs or self._bytes >= self.cap.max_bytes):
            raise StoreFull(self.cap, self._count, self._bytes)

    def _make_room(self, need: int, reserved: int = 0) -> None:
        """Under the write lock, in the insert's transaction: room for a row of ``need`` bytes (:meth:`insert`)."""
        cap = self.cap
        need += reserved
        if self._count + 1 <= cap.max_runs and self._bytes + need <= cap.max_bytes:
            return
        if cap.policy == "refuse" or need > cap.max_bytes:  # (or no eviction can make room)
            raise StoreFull(cap, self._count, self._bytes + reserved, need - reserved)
        rows = self._db.execute(f"SELECT id, {_ROW_BYTES} FROM runs ORDER BY created, rowid").fetchall()
        count, size, drop = self._count, self._bytes, []
        for run_id, nbytes in rows:
            if count + 1 <= cap.max_runs and size + need <= cap.max_bytes:
                break
            drop.append(run_id)
            count, size = count - 1, size - nbytes
        self._db.executemany("DELETE FROM runs WHERE id = ?", [(r,) for r in drop])

    # -- codec (compressor objects are not thread-safe: one per thread) ---------------
    def _codec(self):
        c = getattr(self._local, "codec", None)
        if c is None:
            c = self._local.codec = (zstandard.ZstdCompressor(level=_ZSTD_LEVEL), zstandard.ZstdDecompressor())
        return c

    def _decode(self, blob: bytes) -> bytes:
        if blob[:4] == _ZSTD_MAGIC:
            return self._codec()[1].decompress(blob)
        return zlib.decompress(blob)  # rows written before zstd was used

    @staticmethod
    def piece_decoder(first: bytes) -> tuple[int, Any]:
        """For a document read in pieces (:meth:`document_piece`): its length in bytes (-1 when
        the stored frame does not say) and a decompressor fed piece by piece (``decompress``,
        then ``flush``), chosen by the first piece as :meth:`_decode` chooses."""
        if first[:4] == _ZSTD_MAGIC:
            return zstandard.frame_content_size(first), zstandard.ZstdDecompressor().decompressobj()
        return -1, zlib.decompressobj()  # rows written before zstd was used

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
    def record(self, run_id: str, system: str, status: str, settings: dict, summary: dict, document: bytes) -> tuple:
        """A run as a row, ready for :meth:`insert` (the CPU work: encoding, compression)."""
        return (
            run_id,
            system,
            status,
            orjson.dumps(settings),
            orjson.dumps(summary),
            self._codec()[0].compress(document),
        )

    def add(self, run_id: str, system: str, status: str, settings: dict, summary: dict, document: bytes) -> float:
        """Store one run in one transaction; returns its creation time (Unix s)."""
        return self.insert(self.record(run_id, system, status, settings, summary, document))

    def insert(self, record: tuple, reserved: int = 0) -> float:
        """Write one run (a :meth:`record`) in one transaction, on disk when this returns; ``evict-oldest``
        makes room beside ``reserved`` bytes of other data counted against the cap (the sweeps' rows)."""
        run_id, system, status, settings, summary, blob = record
        created = time.time()
        row = (run_id, created, system, status, settings, summary, blob)
        need = len(settings) + len(summary) + len(blob)

        def write() -> None:
            self._refresh_totals()  # another process (`nmkane store prune`) may have deleted
            self._make_room(need, reserved)
            self._db.execute(
                "INSERT INTO runs (id, created, system, status, settings, summary, document) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                row,
            )

        with self._write_lock:
            self._check_open()
            try:
                self._disk.keep_reserve()
                self._check_disk(need)
                self._transaction(write)
            finally:
                with contextlib.suppress(sqlite3.Error):
                    self._refresh_totals()
        return created

    def _refresh_totals(self) -> None:
        self._count, self._bytes = self._db.execute(
            f"SELECT COUNT(*), COALESCE(SUM({_ROW_BYTES}), 0) FROM runs"
        ).fetchone()

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError("the run store is closed")

    @contextlib.contextmanager
    def _faults(self) -> Iterator[None]:
        """SQLite errors of a known kind raised as their :class:`StoreError`."""
        try:
            yield
        except sqlite3.Error as e:
            fault = store_fault(e, self.path)
            if fault is None:
                raise
            raise fault from e

    def _transaction(self, work: Callable[[], _T]) -> _T:
        """``work()`` in one write transaction (the caller holds the write lock).  On an error
        the transaction is rolled back unless SQLite did so already; an SQLite error of a known
        kind is raised as its :class:`StoreError` and kept in :attr:`fault`."""
        db = self._db
        try:
            db.execute("BEGIN IMMEDIATE")
            result = work()
            db.execute("COMMIT")
        except BaseException as e:
            if db.in_transaction:  # after SQLITE_FULL, SQLite may have rolled back itself
                try:
                    db.execute("ROLLBACK")
                except sqlite3.Error as again:
                    log.warning("%s: rollback after %s failed: %s", self.path, e, again)
            fault = store_fault(e, self.path) if isinstance(e, sqlite3.Error) else None
            if fault is None:
                raise
            self.fault = fault
            raise fault from e
        self.fault = None
        return result

    def _check_disk(self, need: int) -> None:
        """:class:`StoreDiskFull` (kept in :attr:`fault`) before anything is written, when the disk
        cannot take a row of ``need`` bytes (:meth:`DiskRoom.check`)."""
        try:
            with self._faults():
                self._disk.check(self._db, need)
        except StoreDiskFull as e:
            self.fault = e
            raise

    def check_writable(self) -> None:
        """Raise the store's :attr:`fault` again if its last write failed for another reason than
        a full disk and an empty write transaction still fails (``/api/health``)."""
        if self.fault is None or isinstance(self.fault, StoreDiskFull):
            return
        with self._write_lock:
            self._check_open()
            self._transaction(lambda: self._db.execute(_PROBE))

    # -- deleting -------------------------------------------------------------------
    def _freeing(self, work: Callable[[], int]) -> int:
        """A delete (``work()`` returns how many rows).  On a full disk: copy the log into the
        file (the next write starts it over in its own space), release the reserve and try once
        more.  Near a full disk the log is copied after the delete too, ready for the next one."""
        try:
            gone = self._transaction(work)
        except StoreDiskFull:
            self._disk.checkpoint(self._db)
            if self._disk.release_reserve():
                log.warning("%s: the disk is full; its reserve was released for a delete", self.path)
            gone = self._transaction(work)
        self._disk.after_delete(self._db)
        return gone

    def delete(self, run_id: str) -> bool:
        """Delete one run; False when there is none with this id."""
        with self._write_lock:
            self._check_open()
            try:
                gone = self._freeing(lambda: self._db.execute("DELETE FROM runs WHERE id = ?", (run_id,)).rowcount)
            finally:
                with contextlib.suppress(sqlite3.Error):
                    self._refresh_totals()
        return gone > 0

    def prune(self, keep: int | None = None, older_than_s: float | None = None) -> int:
        """Delete all but the newest ``keep`` runs, and/or the runs older than ``older_than_s``
        seconds; returns how many were deleted (in transactions of a few hundred runs, so that a
        full disk needs room for one of them only)."""
        cond: list[str] = []
        args: list[float] = []
        if keep is not None:
            cond.append("id NOT IN (SELECT id FROM runs ORDER BY created DESC, rowid DESC LIMIT ?)")
            args.append(int(keep))
        if older_than_s is not None:
            cond.append("created < ?")
            args.append(time.time() - float(older_than_s))
        if not cond:
            return 0
        with self._write_lock:
            self._check_open()
            with self._faults():
                ids = [r[0] for r in self._db.execute("SELECT id FROM runs WHERE " + " AND ".join(cond), args)]
            gone = 0
            try:
                for start in range(0, len(ids), _PRUNE_BATCH):
                    gone += self._freeing(self._deleting(ids[start : start + _PRUNE_BATCH]))
            finally:
                with contextlib.suppress(sqlite3.Error):
                    self._refresh_totals()
        return gone

    def _deleting(self, ids: list[str]) -> Callable[[], int]:
        return lambda: self._db.executemany("DELETE FROM runs WHERE id = ?", [(i,) for i in ids]).rowcount

    # -- reading --------------------------------------------------------------------
    def document(self, run_id: str) -> bytes | None:
        """The run result document (JSON bytes) as it was served, or None."""
        with self._faults():
            row = self._reader().execute("SELECT document FROM runs WHERE id = ?", (run_id,)).fetchone()
        return None if row is None else self._decode(row[0])

    def document_piece(self, run_id: str, offset: int, size: int) -> bytes | None:
        """``size`` bytes of the *stored* (compressed) document of ``run_id`` from ``offset``
        (b"" past its end), or None when there is no such run: each piece in a read transaction
        of its own (the row found by id, then an incremental read of its blob), so a slow
        download keeps no transaction open (the REST route streams a document with it)."""
        with self._faults():
            con = self._reader()
            con.execute("BEGIN")
            try:
                row = con.execute("SELECT rowid FROM runs WHERE id = ?", (run_id,)).fetchone()
                if row is None:
                    return None
                with con.blobopen("runs", "document", row[0], readonly=True) as blob:
                    blob.seek(min(offset, len(blob)))
                    return blob.read(size)
            finally:
                con.execute("COMMIT")

    def list(self, limit: int, offset: int, system: str | None = None, status: str | None = None) -> list[dict]:
        """Newest first: id, created, system, status, settings, summary."""
        where, args = self._where(system, status)
        with self._faults():
            rows = (
                self._reader()
                .execute(
                    f"SELECT id, created, system, status, settings, summary FROM runs{where} "
                    "ORDER BY created DESC, rowid DESC LIMIT ? OFFSET ?",
                    (*args, limit, offset),
                )
                .fetchall()
            )
        return [
            {
                "id": r[0],
                "created": r[1],
                "system": r[2],
                "status": r[3],
                "settings": orjson.loads(r[4]),
                "summary": orjson.loads(r[5]),
            }
            for r in rows
        ]

    def count(self, system: str | None = None, status: str | None = None) -> int:
        where, args = self._where(system, status)
        with self._faults():
            return self._reader().execute(f"SELECT COUNT(*) FROM runs{where}", args).fetchone()[0]

    def check(self) -> None:
        """Read every page of the file (``PRAGMA quick_check``); :class:`StoreCorrupt` naming
        the first problem found, with how to recover."""
        with self._faults():
            found = [r[0] for r in self._reader().execute("PRAGMA quick_check").fetchall()]
        if found != ["ok"]:
            raise corrupt(self.path, "; ".join(found[:3]) + (f" (and {len(found) - 3} more)" if len(found) > 3 else ""))

    @staticmethod
    def _where(system, status):
        cond: list[str] = []
        args: list[float] = []
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
