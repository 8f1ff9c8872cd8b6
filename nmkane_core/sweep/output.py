"""A sweep's output file: one row per run, streamed, and resumable.

Columns: the varied names (as written on the command line), then ``status``,
``max_abs_violation.<constraint>`` for each constraint, ``max_abs_energy_drift``,
``final_energy_drift``, ``steps``, ``wall_time_s`` and ``message``.  Floats are written by
their exact ``repr``, so a point read back has the key it was written with: resuming reads
the keys already present and the sweep skips those points.

CSV rows are appended and flushed batch by batch (an interrupted sweep keeps every finished
batch; a half-written last line is cut off on resume).  Parquet (needs ``pyarrow``) is
written in row groups to a temporary file that replaces the output when the sweep ends or is
interrupted; resuming a Parquet sweep rewrites the file with the old rows first.
"""

from __future__ import annotations

import csv
import math
import os

from ..errors import InputError
from .spec import point_key

__all__ = ["METRICS", "SweepWriter", "columns", "read_rows"]

METRICS = ("max_abs_energy_drift", "final_energy_drift", "steps", "wall_time_s")


def columns(names: list[str], constraints: list[str]) -> list[str]:
    """The output's columns for these varied names and constraint names."""
    return [*names, "status", *[f"max_abs_violation.{c}" for c in constraints], *METRICS, "message"]


def _cell(v) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    return str(v)


def _value(text: str):
    if text == "":
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        return float(text)
    except ValueError:
        return text


def read_rows(path: str) -> tuple[list[str], list[dict]]:
    """(columns, rows) of a sweep output (CSV or Parquet); numbers come back as numbers."""
    if str(path).endswith(".parquet"):
        pq = _pyarrow()
        table = pq.read_table(path)
        return list(table.column_names), table.to_pylist()
    with open(path, newline="") as f:
        r = csv.reader(f)
        header = next(r, None) or []
        rows = [dict(zip(header, map(_value, row), strict=True)) for row in r if len(row) == len(header)]
    return header, rows


def _pyarrow():
    try:
        import pyarrow.parquet as pq
    except ImportError:
        raise InputError(
            "--out", "FILE.parquet", "FILE.csv (or install pyarrow for .parquet)", "pyarrow is not installed"
        ) from None
    return pq


def check_out(path: str) -> None:
    """Refuse an output name that is neither .csv nor .parquet, or .parquet without pyarrow."""
    if not str(path).endswith((".csv", ".parquet")):
        raise InputError("--out", path, "a file name ending in .csv or .parquet", "unknown format")
    if str(path).endswith(".parquet"):
        _pyarrow()


class SweepWriter:
    """Streams rows to ``path``; ``done`` holds the keys of rows already there (resume)."""

    def __init__(self, path: str | os.PathLike, names: list[str], constraints: list[str], resume: bool = True):
        check_out(str(path))
        self.path, self.names = str(path), list(names)
        self.columns = columns(names, constraints)
        self.done: set = set()
        self.parquet = self.path.endswith(".parquet")
        self.written = 0
        old_rows: list[dict] = []
        if resume and os.path.exists(self.path) and os.path.getsize(self.path) > 0:
            if not self.parquet:
                _cut_partial_line(self.path)
            header, old_rows = read_rows(self.path)
            if header != self.columns:
                raise InputError(
                    "--out",
                    self.path,
                    f"an output of this sweep (columns {', '.join(self.columns)})",
                    "the file exists with other columns; choose another file or remove it",
                )
            self.done = {point_key(r, self.names) for r in old_rows}
        if self.parquet:
            self._open_parquet(old_rows)
        else:
            fresh = not self.done
            self.file = open(self.path, "w" if fresh else "a", newline="")  # noqa: SIM115 (closed by close())
            self.csv = csv.writer(self.file, lineterminator="\n")
            if fresh:
                self.csv.writerow(self.columns)
                self.file.flush()

    def _open_parquet(self, old_rows):
        import pyarrow as pa

        pq = _pyarrow()
        self.tmp = self.path + ".part"
        self.schema = None
        self.pa, self.pq, self.pw = pa, pq, None
        if old_rows:
            self._write_parquet(old_rows)

    def _type(self, column: str, rows: list[dict]):
        pa = self.pa
        if column in ("status", "message"):
            return pa.string()
        if column == "steps":
            return pa.int64()
        if column not in self.names:
            return pa.float64()
        words = any(isinstance(r.get(column), str) for r in rows)
        return pa.string() if words else pa.float64()

    def _write_parquet(self, rows):
        if self.pw is None:
            self.schema = self.pa.schema([(c, self._type(c, rows)) for c in self.columns])
            self.pw = self.pq.ParquetWriter(self.tmp, self.schema)
        table = self.pa.Table.from_pylist([{c: r.get(c) for c in self.columns} for r in rows], schema=self.schema)
        self.pw.write_table(table)

    def write(self, rows: list[dict]) -> None:
        """Append rows (dicts by column; missing columns stay empty) and flush."""
        if self.parquet:
            self._write_parquet(rows)
        else:
            for r in rows:
                self.csv.writerow([_cell(r.get(c)) for c in self.columns])
            self.file.flush()
        self.written += len(rows)

    def close(self) -> None:
        if self.parquet:
            if self.pw is not None:
                self.pw.close()
                os.replace(self.tmp, self.path)
        else:
            self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _cut_partial_line(path: str) -> None:
    """An interrupted write may leave a last line without its newline: drop it."""
    with open(path, "rb+") as f:
        data = f.read()
        if data and not data.endswith(b"\n"):
            f.truncate(data.rfind(b"\n") + 1)
