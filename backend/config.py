"""Service settings: where runs are stored and the limits every request is held to.

Each limit is exposed in ``GET /api/systems`` under ``service_limits``; environment
variables override the defaults (``NMKANE_DATA_DIR``, ``NMKANE_DB``,
``NMKANE_MAX_CONCURRENT_RUNS``, ``NMKANE_QUEUE_LIMIT``, ``NMKANE_MAX_STEPS``,
``NMKANE_MAX_ROWS``, ``NMKANE_MAX_REQUEST_BYTES``, ``NMKANE_MAX_WALL_TIME_S``,
``NMKANE_CORS_ORIGINS`` — comma separated, empty by default: CORS closed).
"""

from __future__ import annotations

import os
from dataclasses import asdict, dataclass, field
from pathlib import Path


def _env(name, default, cast):
    value = os.environ.get(name)
    return default if value in (None, "") else cast(value)


@dataclass
class Settings:
    #: directory of the embedded database
    data_dir: Path = field(default_factory=lambda: Path(_env("NMKANE_DATA_DIR", "data", str)))
    #: the SQLite file (default: data_dir/runs.sqlite3)
    db_path: Path | None = field(default_factory=lambda: _env("NMKANE_DB", None, Path))
    #: simulations running at once (worker threads; the compiled loops release the GIL)
    max_concurrent_runs: int = field(default_factory=lambda: _env("NMKANE_MAX_CONCURRENT_RUNS",
                                                                 os.cpu_count() or 2, int))
    #: runs admitted (running + waiting); past it POST /api/runs answers 503 + Retry-After
    queue_limit: int = field(default_factory=lambda: _env("NMKANE_QUEUE_LIMIT", 64, int))
    #: fixed steps per run (t_final/dt); more is refused with 422 before the run starts
    max_steps: int = field(default_factory=lambda: _env("NMKANE_MAX_STEPS", 2_000_000, int))
    #: output rows per run (t_final/dt/every); more is refused with 422 (use `every`)
    max_rows: int = field(default_factory=lambda: _env("NMKANE_MAX_ROWS", 100_000, int))
    #: request body size; more is refused with 413
    max_request_bytes: int = field(default_factory=lambda: _env("NMKANE_MAX_REQUEST_BYTES", 65_536, int))
    #: wall time per run; a run past it ends with status "timeout" and what it computed
    max_wall_time_s: float = field(default_factory=lambda: _env("NMKANE_MAX_WALL_TIME_S", 10.0, float))
    #: origins allowed by CORS (none by default)
    cors_origins: tuple[str, ...] = field(default_factory=lambda: tuple(
        o for o in _env("NMKANE_CORS_ORIGINS", "", str).split(",") if o))
    #: load the compiled kernels when the app starts (tests may turn it off)
    warm_kernels: bool = True

    @property
    def database(self) -> Path:
        return Path(self.db_path) if self.db_path else Path(self.data_dir) / "runs.sqlite3"

    def limits(self) -> dict:
        d = asdict(self)
        return {k: d[k] for k in ("max_concurrent_runs", "queue_limit", "max_steps", "max_rows",
                                  "max_request_bytes", "max_wall_time_s")}
