"""The run store's file and disk: what an SQLite fault means for it, and the room a write needs.

Faults: every SQLite error of a known kind (its result code, or the words of its message for an
error made without one) becomes a :class:`StoreError` naming the file, what happened and what to
do — a full disk (:class:`StoreDiskFull`: 507 from the service), a store that cannot be written
(:class:`StoreReadOnly`), a damaged, truncated or foreign file (:class:`StoreCorrupt`), a
directory in the file's place, a lock held too long, an I/O error (:class:`StoreUnavailable`):
503.  The CLI prints it on one line.

Room (:class:`DiskRoom`): a write-ahead log needs the disk twice over for a while — a new run's
pages go into the log first and into the file at the next checkpoint — and a log that can no
longer be copied into the file (the disk full meanwhile) leaves SQLite unable to write anything,
deletes included.  So a new run is refused *before* anything is written when the disk cannot
take it that way; near a full disk the log is copied into the file first and kept to about one
run's size (``journal_size_limit``).  For deletes on a full disk the store holds a reserve,
``<file>-reserve`` (:data:`RESERVE_BYTES`): released when a delete, or the opening of the
store, meets a full disk, and held again when there is room.  New runs never take the reserve's
room.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sqlite3
from pathlib import Path

from nmkane_core.errors import NmkaneError

__all__ = [
    "RESERVE_BYTES",
    "DiskRoom",
    "StoreError",
    "StoreDiskFull",
    "StoreReadOnly",
    "StoreCorrupt",
    "StoreUnavailable",
    "cannot_open",
    "corrupt",
    "disk_full",
    "free_bytes",
    "store_fault",
]

#: disk held in ``<file>-reserve`` for deletes on a full disk (a delete of 100 runs writes ~60 kB)
RESERVE_BYTES = 256 * 1024
_MARGIN = 64 * 1024  # room left on the disk besides a run (the log's index grows too)
_LOW = 16 * 1024 * 1024  # less free than this beside the log: deletes copy the log into the file


class StoreError(NmkaneError):
    """The run store's file or disk failed: ``path``, ``reason`` (what happened), ``remedy``
    (what to do), the HTTP ``status`` and error ``kind`` the service answers with."""

    status = 503
    kind = "store_unavailable"

    def __init__(self, path: Path | str, reason: str, remedy: str, sqlite_message: str | None = None):
        self.path, self.reason, self.remedy = Path(path), reason, remedy
        said = f" (SQLite: {sqlite_message})" if sqlite_message else ""
        super().__init__(f"{path}: {reason}{said}; {remedy}")


class StoreDiskFull(StoreError):
    """The disk holding the store is full (or the file may not grow): new runs are refused."""

    status = 507
    kind = "disk_full"


class StoreReadOnly(StoreError):
    """The store cannot be written (a read-only file, directory or filesystem)."""

    kind = "store_read_only"


class StoreCorrupt(StoreError):
    """The file is damaged, truncated or not an SQLite database."""

    kind = "store_corrupt"


class StoreUnavailable(StoreError):
    """The store cannot be opened or read: a directory in its place, a lock, an I/O error."""


_ELSEWHERE = "or set NMKANE_DB (or NMKANE_DATA_DIR) to another place"
#: SQLite's primary result codes (``sqlite_errorcode & 0xff``) and, for errors made without
#: one, the words of its messages: the kind of fault each one is
_CODES = {13: "full", 8: "read-only", 11: "corrupt", 26: "corrupt", 14: "cannot-open", 10: "io", 5: "locked"}
_WORDS = (
    ("disk is full", "full"),
    ("readonly database", "read-only"),
    ("malformed", "corrupt"),
    ("not a database", "corrupt"),
    ("unable to open", "cannot-open"),
    ("disk i/o error", "io"),
    ("database is locked", "locked"),
)


def free_bytes(folder: Path) -> int:
    """Bytes free on the filesystem holding ``folder`` (for this user); huge when unknown."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return 2**62


def _fault_kind(exc: BaseException) -> str | None:
    code = getattr(exc, "sqlite_errorcode", None)
    if isinstance(code, int) and (code & 0xFF) in _CODES:
        return _CODES[code & 0xFF]
    words = str(exc).lower()
    return next((kind for text, kind in _WORDS if text in words), None)


def _room(grow: int, short: int) -> int:
    """Bytes a write needs free: what the files grow by, the reserve's missing part, a margin."""
    return grow + short + (_MARGIN if grow else 0)


def _amount(nbytes: int) -> str:
    return f"{nbytes / 1e6:,.1f} MB" if nbytes >= 1e6 else f"{nbytes / 1e3:,.0f} kB"


def disk_full(path: Path, free: int, need: int | None = None, sqlite_message: str | None = None) -> StoreDiskFull:
    """The :class:`StoreDiskFull` of the store at ``path`` (``free``, ``need``: bytes)."""
    needed = "" if need is None else f", {_amount(need)} needed for this run and the room kept for deletes"
    return StoreDiskFull(
        path,
        f"the disk is full: the run store cannot grow ({_amount(free)} free on its disk{needed})",
        f"free disk space in {path.parent}, or delete runs (DELETE /api/runs/{{id}}, `nmkane store prune`): "
        "new runs reuse the space of deleted ones",
        sqlite_message,
    )


def corrupt(path: Path, sqlite_message: str | None) -> StoreCorrupt:
    """The :class:`StoreCorrupt` of the store at ``path``, with how to recover."""
    return StoreCorrupt(
        path,
        "the run store is damaged, truncated or not an SQLite file",
        f"stop the service, move the file aside (with {path.name}-wal and {path.name}-shm if there) "
        "and start again with a new, empty store; `sqlite3 MOVED-FILE .recover | sqlite3 NEW-FILE` "
        "salvages the runs that can still be read",
        sqlite_message,
    )


def cannot_open(path: Path, reason: str, sqlite_message: str | None = None) -> StoreUnavailable:
    """The :class:`StoreUnavailable` of a store that cannot be opened for ``reason``."""
    return StoreUnavailable(path, reason, f"check the file and its directory, {_ELSEWHERE}", sqlite_message)


def store_fault(exc: BaseException, path: Path | str) -> StoreError | None:
    """The :class:`StoreError` that an SQLite error ``exc`` means for the store at ``path``, or
    None when it is of no kind known here (a bug, a constraint: it stays what it is).  Known by
    SQLite's result code, or by its message for an error made without one."""
    path = Path(path)
    kind = _fault_kind(exc)
    said = str(exc)
    if kind == "io" and free_bytes(path.parent) < _MARGIN:  # a write that met a full disk
        kind = "full"
    if kind == "full":
        return disk_full(path, free_bytes(path.parent), sqlite_message=said)
    if kind == "read-only":
        return StoreReadOnly(
            path,
            "the run store cannot be written (a read-only file, directory or filesystem)",
            f"make the file and its directory writable by the user running nmkane, {_ELSEWHERE}",
            said,
        )
    if kind == "corrupt":
        return corrupt(path, said)
    if kind == "cannot-open" and path.is_dir():
        return StoreUnavailable(path, "is a directory, not a run store", f"remove or rename it, {_ELSEWHERE}")
    if kind == "cannot-open":
        return StoreUnavailable(
            path,
            "the run store cannot be opened",
            f"check that its directory exists and can be written by the user running nmkane, {_ELSEWHERE}",
            said,
        )
    if kind == "locked":
        return StoreUnavailable(
            path,
            "the run store stayed locked by another process for 30 s",
            "retry; if it lasts, find the process holding it (fuser FILE)",
            said,
        )
    if kind == "io":
        return StoreUnavailable(
            path,
            "an I/O error on the run store's disk",
            "check the disk (is it still mounted? the kernel log says more) and retry",
            said,
        )
    return None


def _allocate(fd: int, size: int) -> None:
    """Make the file ``fd`` at least ``size`` bytes, with its blocks taken from the disk
    (OSError when the disk has no room)."""
    if hasattr(os, "posix_fallocate"):
        os.posix_fallocate(fd, 0, size)
        return
    have = os.fstat(fd).st_size  # no fallocate (macOS): zeros written take blocks too
    if have < size:
        os.pwrite(fd, bytes(size - have), have)
        os.fsync(fd)


class DiskRoom:
    """The room the store at ``path`` has on its disk: its reserve, its log, the check before a
    new run (``page``: the file's page size, set once the file is open)."""

    def __init__(self, path: Path):
        self.path = path
        self.page = 4096
        self.reserve = path.with_name(path.name + "-reserve")
        self._wal = path.with_name(path.name + "-wal")
        self._held = 0
        self._log_limit = -1

    def keep_reserve(self) -> None:
        """Hold :data:`RESERVE_BYTES` of the disk in ``<file>-reserve`` for deletes on a full
        disk; where there is no room for it now, it is made again at a later write."""
        if self._held >= RESERVE_BYTES:
            return
        try:
            fd = os.open(self.reserve, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError:
            return
        try:
            have = os.fstat(fd).st_size
            try:
                _allocate(fd, RESERVE_BYTES)
                self._held = RESERVE_BYTES
            except OSError:  # no room: keep what was held, claim no part of the disk's last bytes
                os.ftruncate(fd, have)
                self._held = have
        except OSError:
            pass
        finally:
            os.close(fd)

    def release_reserve(self) -> bool:
        """Give the reserve back to the disk (a delete met a full disk); whether there was one."""
        had = self._held > 0 or (self.reserve.exists() and self.reserve.stat().st_size > 0)
        with contextlib.suppress(OSError):
            os.truncate(self.reserve, 0)
        self._held = 0
        return had

    def checkpoint(self, db: sqlite3.Connection) -> tuple[int, int, int] | None:
        """Copy the write-ahead log into the file (``PRAGMA wal_checkpoint(PASSIVE)``), so the
        next write starts the log over and reuses its space: ``(busy, frames in the log,
        frames copied)``, None when it failed (the disk cannot take the file's growth)."""
        try:
            return db.execute("PRAGMA wal_checkpoint(PASSIVE)").fetchone()
        except sqlite3.Error:
            return None

    def check(self, db: sqlite3.Connection, need: int) -> None:
        """Raise :class:`StoreDiskFull`, before anything is written, when the disk cannot take a
        row of ``need`` bytes: its pages in the log, then in the file at the next checkpoint,
        with the pages the log holds already and the reserve kept whole.  Near a full disk the
        log is copied into the file first, and kept to about one run's size."""
        free = free_bytes(self.path.parent)
        pages = -(-need // (self.page - 4)) + 2  # overflow pages; a split of the table's or index's leaf
        log_bytes = (pages + 1) * (self.page + 24) + 32  # frames (24-byte header + page; page 1 too), header
        short = RESERVE_BYTES - self._held
        if free >= 2 * log_bytes + self._log_size() + short + _MARGIN:
            self._keep_log(db, -1)
            return  # room enough whatever the log holds: no need to look closer
        self._keep_log(db, max(log_bytes, RESERVE_BYTES))  # not the last 4 MB of runs, as SQLite keeps them
        pending, reusable = self._copy_log(db)
        free = free_bytes(self.path.parent)  # after the file took what the log held
        free_pages = db.execute("PRAGMA freelist_count").fetchone()[0]  # pages of deleted runs
        grow_file = max(0, pages - free_pages) * self.page
        need_free = _room(grow_file + max(0, log_bytes - reusable) + pending, short)
        if free < need_free and pending == 0 and free + reusable >= _room(grow_file + log_bytes, short):
            # the log, all copied, holds more than this run needs: its room back to the disk makes it fit
            with contextlib.suppress(sqlite3.Error):
                db.execute("PRAGMA wal_checkpoint(TRUNCATE)").fetchone()
            free, need_free = free_bytes(self.path.parent), _room(grow_file + log_bytes, short)
        if free < need_free:
            raise disk_full(self.path, free, need_free)

    def _log_size(self) -> int:
        return self._wal.stat().st_size if self._wal.exists() else 0

    def _copy_log(self, db: sqlite3.Connection) -> tuple[int, int]:
        """Copy the log into the file: ``(bytes of log frames still to copy, bytes of the log the
        next write can reuse)``."""
        done = self.checkpoint(db)
        frame = self.page + 24
        if done is None or done[1] < 0:
            return self._log_size(), 0
        if done[0] or done[1] != done[2]:  # a reader holds part of it: the next write appends
            return (done[1] - done[2]) * frame, max(0, self._log_size() - 32 - done[1] * frame)
        return 0, self._log_size()  # all copied: the next write starts the log over, in its own space

    def _keep_log(self, db: sqlite3.Connection, size: int) -> None:
        """Truncate the log to ``size`` bytes when it starts over (``journal_size_limit``; -1:
        never, SQLite's default)."""
        if size != self._log_limit:
            db.execute(f"PRAGMA journal_size_limit = {int(size)}")
            self._log_limit = size

    def after_delete(self, db: sqlite3.Connection) -> None:
        """Near a full disk, copy the log into the file, ready for the next delete; hold the
        reserve again where there is room."""
        if free_bytes(self.path.parent) < self._log_size() + _LOW:
            self.checkpoint(db)
        self.keep_reserve()
