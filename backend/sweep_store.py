"""The REST sweeps' store: tables ``sweeps`` and ``sweep_rows`` in the service's SQLite file.

A sweep belongs to the process that runs it (column ``owner``: host, pid and the process's
start time).  When the store opens — at the service's start — a sweep left ``queued`` or
``running`` by a process that is no longer there (killed, or the machine restarted) is
marked ``interrupted``: it is not resumed (its rows so far stay readable; POST the request
again to run it anew).  A sweep of another live service sharing the file is left alone; a
process on another host counts as gone (a SQLite file is not shared between machines).

Faults of the file and the disk are raised as the run store's :class:`~backend.store.StoreError`
(a full disk: :class:`~backend.store.StoreDiskFull`, 507 from ``POST /api/sweeps``), and a
transaction is rolled back only while SQLite has not done so itself.
"""

from __future__ import annotations

import contextlib
import os
import socket
import sqlite3
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import orjson

from .store import StoreUnavailable, store_fault

__all__ = ["SCHEMA", "SweepStore", "owner_alive", "process_owner"]

SCHEMA = """
CREATE TABLE IF NOT EXISTS sweeps (
    id       TEXT PRIMARY KEY,
    created  REAL NOT NULL,
    system   TEXT NOT NULL,
    status   TEXT NOT NULL,
    total    INTEGER NOT NULL,
    done     INTEGER NOT NULL,
    request  BLOB NOT NULL,          -- JSON: the request as received
    columns  BLOB NOT NULL,          -- JSON: the output columns
    message  TEXT NOT NULL DEFAULT '',
    owner    TEXT NOT NULL DEFAULT ''  -- host:pid:start of the process running it
);
CREATE TABLE IF NOT EXISTS sweep_rows (
    sweep_id TEXT NOT NULL,
    seq      INTEGER NOT NULL,
    row      BLOB NOT NULL,          -- JSON: one run's row
    PRIMARY KEY (sweep_id, seq)
);
"""


def _start_time(pid: int) -> str | None:
    """When process ``pid`` started (clock ticks since boot, from /proc), '' where /proc is
    missing, None if there is no such process."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[19]
    except FileNotFoundError:
        if os.path.isdir("/proc/self"):
            return None
    except (OSError, IndexError):
        return ""
    try:  # no /proc: whether the pid exists at all
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except OSError:
        pass
    return ""


def process_owner(pid: int | None = None) -> str:
    """``host:pid:start`` of a process (this one by default): a pid reused later differs in start."""
    pid = os.getpid() if pid is None else pid
    return f"{socket.gethostname()}:{pid}:{_start_time(pid) or ''}"


def owner_alive(owner: str) -> bool:
    """Whether the process named by ``owner`` (:func:`process_owner`) still runs.  Another
    host's process counts as gone: a SQLite file is not shared between machines."""
    host, _, rest = owner.partition(":")
    pid_text, _, start = rest.partition(":")
    if host != socket.gethostname() or not pid_text.isdigit():
        return False
    now = _start_time(int(pid_text))
    return now is not None and (now == start or "" in (now, start))


class SweepStore:
    """The sweeps of one SQLite file (the service's run database); one writer connection.

    Opening it marks the sweeps of processes that are gone ``interrupted`` (:meth:`interrupt_orphans`)."""

    def __init__(self, path):
        self.path = Path(path)
        self._lock = threading.Lock()
        with self._faults(opening=True):
            self._db = sqlite3.connect(path, check_same_thread=False, isolation_level=None, timeout=30)
            self._db.execute("PRAGMA journal_mode=WAL")
            self._db.executescript(SCHEMA)
            cols = {r[1] for r in self._db.execute("PRAGMA table_info(sweeps)")}
            if "owner" not in cols:  # a file from before the column
                with contextlib.suppress(sqlite3.OperationalError):  # another process added it meanwhile
                    self._db.execute("ALTER TABLE sweeps ADD COLUMN owner TEXT NOT NULL DEFAULT ''")
        self.owner = process_owner()
        self.interrupted = self.interrupt_orphans()

    @contextlib.contextmanager
    def _faults(self, opening: bool = False) -> Iterator[None]:
        """SQLite errors of a known kind (any kind, ``opening``) raised as the run store's
        :class:`~backend.store.StoreError`."""
        try:
            yield
        except sqlite3.Error as e:
            if opening and getattr(self, "_db", None) is not None:
                self._db.close()
            fault = store_fault(e, self.path)
            if fault is None and opening:
                fault = StoreUnavailable(self.path, "the sweeps' tables cannot be opened", "check the file", str(e))
            if fault is None:
                raise
            raise fault from e

    def interrupt_orphans(self) -> list[str]:
        """Mark ``interrupted`` every queued or running sweep whose process is gone; their ids."""
        with self._lock, self._faults():
            found = self._db.execute(
                "SELECT id, owner, done, total FROM sweeps WHERE status IN ('queued', 'running')"
            ).fetchall()
        gone = [r for r in found if not owner_alive(r[1])]
        if gone:
            self._tx(
                [
                    (
                        "UPDATE sweeps SET status = 'interrupted', message = ? "
                        "WHERE id = ? AND status IN ('queued', 'running')",
                        (
                            f"the service stopped after {done} of {total} runs; the rows so far are kept; "
                            "POST the request again to run it anew",
                            sweep_id,
                        ),
                    )
                    for sweep_id, _, done, total in gone
                ]
            )
        return [r[0] for r in gone]

    def _tx(self, statements):
        with self._lock, self._faults():
            self._db.execute("BEGIN IMMEDIATE")
            try:
                for sql, args in statements:
                    if args and isinstance(args, list):
                        self._db.executemany(sql, args)
                    else:
                        self._db.execute(sql, args or ())
                self._db.execute("COMMIT")
            except BaseException:
                if self._db.in_transaction:  # after SQLITE_FULL, SQLite may have rolled back itself
                    with contextlib.suppress(sqlite3.Error):
                        self._db.execute("ROLLBACK")
                raise

    def create(self, sweep_id, system, total, request: dict, columns: list[str]) -> float:
        created = time.time()
        self._tx(
            [
                (
                    "INSERT INTO sweeps (id, created, system, status, total, done, request, columns, owner) "
                    "VALUES (?, ?, ?, 'queued', ?, 0, ?, ?, ?)",
                    (sweep_id, created, system, total, orjson.dumps(request), orjson.dumps(columns), self.owner),
                )
            ]
        )
        return created

    def set_status(self, sweep_id, status, message=""):
        self._tx([("UPDATE sweeps SET status = ?, message = ? WHERE id = ?", (status, message, sweep_id))])

    def add_rows(self, sweep_id, start: int, rows: list[dict]) -> None:
        """Rows ``start``, ``start + 1``, ... of a sweep, and its progress, in one transaction."""
        data = [(sweep_id, start + i, orjson.dumps(r)) for i, r in enumerate(rows)]
        self._tx(
            [
                ("INSERT INTO sweep_rows (sweep_id, seq, row) VALUES (?, ?, ?)", data),
                ("UPDATE sweeps SET done = ? WHERE id = ?", (start + len(rows), sweep_id)),
            ]
        )

    def size(self) -> int:
        """Bytes of the sweeps' stored rows and requests (counted against ``max_store_bytes``)."""
        with self._lock, self._faults():
            rows = self._db.execute("SELECT COALESCE(SUM(length(row)), 0) FROM sweep_rows").fetchone()[0]
            requests = self._db.execute("SELECT COALESCE(SUM(length(request)), 0) FROM sweeps").fetchone()[0]
        return int(rows) + int(requests)

    def get(self, sweep_id) -> dict | None:
        with self._lock, self._faults():
            r = self._db.execute(
                "SELECT id, created, system, status, total, done, columns, message FROM sweeps WHERE id = ?",
                (sweep_id,),
            ).fetchone()
        if r is None:
            return None
        return {
            "id": r[0],
            "created": r[1],
            "system": r[2],
            "status": r[3],
            "total": r[4],
            "done": r[5],
            "columns": orjson.loads(r[6]),
            "message": r[7],
        }

    def rows(self, sweep_id, offset=0, limit=-1) -> list[dict]:
        with self._lock, self._faults():
            got = self._db.execute(
                "SELECT row FROM sweep_rows WHERE sweep_id = ? ORDER BY seq LIMIT ? OFFSET ?", (sweep_id, limit, offset)
            ).fetchall()
        return [orjson.loads(r[0]) for r in got]
