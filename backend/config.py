"""Service settings: where runs are stored and the limits every request is held to.

Every field can be given to :class:`Settings` directly (tests do) or through an
environment variable (``nmkane serve`` does).  The limits are exposed, with the
descriptions below, in ``GET /api/systems`` under ``service_limits``.

=============================  ===========================  =================================
setting                        environment variable         default
=============================  ===========================  =================================
``data_dir``                   ``NMKANE_DATA_DIR``          ``./data``
``db_path``                    ``NMKANE_DB``                ``data_dir/runs.sqlite3``
``max_concurrent_runs``        ``NMKANE_MAX_CONCURRENT_RUNS``  number of CPU cores
``queue_limit``                ``NMKANE_QUEUE_LIMIT``       64
``max_steps``                  ``NMKANE_MAX_STEPS``         2,000,000
``max_rows``                   ``NMKANE_MAX_ROWS``          100,000
``max_request_bytes``          ``NMKANE_MAX_REQUEST_BYTES`` 65,536
``max_wall_time_s``            ``NMKANE_MAX_WALL_TIME_S``   10 s
``cors_origins``               ``NMKANE_CORS_ORIGINS``      none (comma-separated list)
``max_stored_runs``            ``NMKANE_MAX_STORED_RUNS``   100,000
``max_store_bytes``            ``NMKANE_MAX_STORE_MB``      2,000 MB (rows: settings, summary,
                                                            compressed document)
``store_full``                 ``NMKANE_STORE_FULL``        ``refuse`` (507) | ``evict-oldest``
``read_timeout_s``             ``NMKANE_READ_TIMEOUT_S``    10 s (a request's head and body)
``allowed_hosts``              ``NMKANE_ALLOWED_HOSTS``     loopback names (+ the bound address)
``token``                      ``NMKANE_TOKEN``             none on loopback (see ``nmkane serve``)
=============================  ===========================  =================================

The defaults of ``max_steps`` and ``max_rows`` have their home in the core,
``nmkane_core.schema.REST_DEFAULT_LIMITS``, which quotes them without importing backend.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from nmkane_core.schema import REST_DEFAULT_LIMITS

from .store import POLICIES, StoreCap

__all__ = ["Settings", "LIMIT_DESCRIPTIONS"]

#: What each limit means (also served in ``GET /api/systems``).
LIMIT_DESCRIPTIONS = {
    "max_concurrent_runs": "simulations running at once (worker threads; the compiled loops release "
    "the GIL, so they run in parallel)",
    "queue_limit": "runs admitted at once, running plus waiting; past it POST /api/runs answers 503 "
    "with a Retry-After header instead of queueing more",
    "max_steps": "fixed steps per run (t_final/dt); a request over it is refused with 422 before the "
    "run starts. Adaptive and scipy integrators are bounded by max_wall_time_s instead",
    "max_rows": "output rows per run; a fixed-step request over it is refused with 422 (raise `every`); "
    "an adaptive run stops when its output reaches it (status 'timeout', the message says why, "
    "results up to there kept)",
    "max_request_bytes": "size of a request body; a larger one is refused with 413",
    "max_wall_time_s": "integration wall time per run, s; a run past it ends with status 'timeout' "
    "and keeps what it computed so far",
    "max_stored_runs": "runs kept in the store; when full, a new run is refused with 507 (policy 'refuse', the "
    "default: a stored run is never deleted behind anyone's back) or the oldest runs are "
    "deleted to make room (policy 'evict-oldest', NMKANE_STORE_FULL); delete runs with "
    "DELETE /api/runs/{id} or `nmkane store prune`",
    "max_store_bytes": "bytes of stored rows (settings, summary, compressed document), same policy as max_stored_runs",
    "read_timeout_s": "seconds a client has to send a request's head and its body; a slower one is cut off",
}


def _env(name: str, default, cast):
    raw = os.environ.get(name)
    if raw is None or raw.strip() == "":
        return default
    try:
        return cast(raw.strip())
    except ValueError:
        raise ValueError(f"environment variable {name}={raw!r} is not a valid {cast.__name__}") from None


def _origins(raw: str) -> tuple[str, ...]:
    return tuple(o.strip() for o in raw.split(",") if o.strip())


@dataclass
class Settings:
    """Where the service keeps its runs, and its limits (see the module docstring)."""

    #: directory of the embedded database (created if missing)
    data_dir: Path = field(default_factory=lambda: Path(_env("NMKANE_DATA_DIR", "data", str)))
    #: the SQLite file; None means ``data_dir/runs.sqlite3``
    db_path: Path | None = field(default_factory=lambda: _env("NMKANE_DB", None, Path))
    #: simulations running at once
    max_concurrent_runs: int = field(
        default_factory=lambda: _env("NMKANE_MAX_CONCURRENT_RUNS", os.cpu_count() or 2, int)
    )
    #: runs admitted at once (running + waiting); past it: 503 + Retry-After
    queue_limit: int = field(default_factory=lambda: _env("NMKANE_QUEUE_LIMIT", 64, int))
    #: fixed steps per run; more is refused with 422 before the run starts
    max_steps: int = field(default_factory=lambda: _env("NMKANE_MAX_STEPS", REST_DEFAULT_LIMITS["max_steps"], int))
    #: output rows per run; more is refused with 422 (fixed step) or stops the run (adaptive)
    max_rows: int = field(default_factory=lambda: _env("NMKANE_MAX_ROWS", REST_DEFAULT_LIMITS["max_rows"], int))
    #: request body size in bytes; more is refused with 413
    max_request_bytes: int = field(default_factory=lambda: _env("NMKANE_MAX_REQUEST_BYTES", 65_536, int))
    #: integration wall time per run, s; a run past it ends with status "timeout"
    max_wall_time_s: float = field(default_factory=lambda: _env("NMKANE_MAX_WALL_TIME_S", 10.0, float))
    #: origins allowed by CORS; empty (the default) means CORS stays closed
    cors_origins: tuple[str, ...] = field(default_factory=lambda: _origins(_env("NMKANE_CORS_ORIGINS", "", str)))
    #: runs kept in the store (see ``store_full``)
    max_stored_runs: int = field(default_factory=lambda: _env("NMKANE_MAX_STORED_RUNS", 100_000, int))
    #: bytes of stored rows (see ``store_full``)
    max_store_bytes: int = field(default_factory=lambda: _env("NMKANE_MAX_STORE_MB", 2_000, int) * 1_000_000)
    #: a full store: "refuse" new runs (507) or "evict-oldest" runs to make room
    store_full: str = field(default_factory=lambda: _env("NMKANE_STORE_FULL", "refuse", str))
    #: seconds to receive a request's head and body; slower clients are disconnected (408)
    read_timeout_s: float = field(default_factory=lambda: _env("NMKANE_READ_TIMEOUT_S", 10.0, float))
    #: Host header values accepted besides the loopback names (the bound address is added by serve)
    allowed_hosts: tuple[str, ...] = field(default_factory=lambda: _origins(_env("NMKANE_ALLOWED_HOSTS", "", str)))
    #: a token every write must carry (``Authorization: Bearer``); None: no token asked for
    token: str | None = field(default_factory=lambda: _env("NMKANE_TOKEN", None, str))
    #: load the compiled kernels when the app starts, so no request pays for it
    warm_kernels: bool = True

    def __post_init__(self) -> None:
        self.data_dir = Path(self.data_dir)
        self.db_path = None if self.db_path is None else Path(self.db_path)
        if isinstance(self.cors_origins, str):
            self.cors_origins = _origins(self.cors_origins)
        self.cors_origins = tuple(self.cors_origins)
        if isinstance(self.allowed_hosts, str):
            self.allowed_hosts = _origins(self.allowed_hosts)
        self.allowed_hosts = tuple(h.lower() for h in self.allowed_hosts)
        for name, low in (
            ("max_concurrent_runs", 1),
            ("queue_limit", 0),
            ("max_steps", 1),
            ("max_rows", 2),
            ("max_request_bytes", 1),
            ("max_stored_runs", 1),
            ("max_store_bytes", 1),
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < low:
                raise ValueError(f"Settings.{name} = {value!r}: an integer ≥ {low} is needed")
        if not (isinstance(self.max_wall_time_s, (int, float)) and self.max_wall_time_s > 0):
            raise ValueError(f"Settings.max_wall_time_s = {self.max_wall_time_s!r}: a number > 0 s is needed")
        if not (isinstance(self.read_timeout_s, (int, float)) and self.read_timeout_s > 0):
            raise ValueError(f"Settings.read_timeout_s = {self.read_timeout_s!r}: a number > 0 s is needed")
        if self.store_full not in POLICIES:
            raise ValueError(
                f"Settings.store_full = {self.store_full!r}: one of {', '.join(POLICIES)} "
                "(environment variable NMKANE_STORE_FULL)"
            )
        if self.token is not None and len(self.token) < 16:
            raise ValueError("Settings.token: at least 16 characters (NMKANE_TOKEN); `nmkane serve` makes one")
        if "*" in self.cors_origins:
            raise ValueError("Settings.cors_origins: list the allowed origins; '*' is not accepted")

    @property
    def database(self) -> Path:
        """The SQLite file the runs are stored in."""
        return self.db_path if self.db_path is not None else self.data_dir / "runs.sqlite3"

    @property
    def store_cap(self) -> StoreCap:
        return StoreCap(self.max_stored_runs, self.max_store_bytes, self.store_full)

    def limits(self) -> dict:
        """The limits as served in ``GET /api/systems``."""
        return {name: getattr(self, name) for name in LIMIT_DESCRIPTIONS}
