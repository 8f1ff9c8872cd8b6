"""Service settings: where runs are stored, the limits every request is held to, and exposure.

One class, :class:`Settings` (pydantic-settings).  Every field can be given to it directly
(tests do) or through the environment variable ``NMKANE_<FIELD>`` (``nmkane serve`` does):
``NMKANE_MAX_ROWS=50000``.  Two names differ: ``db_path`` is ``NMKANE_DB``, and
``max_store_bytes`` is set in megabytes by ``NMKANE_MAX_STORE_MB``.  Lists
(``cors_origins``, ``allowed_hosts``) are comma-separated; an empty variable is the default.
This module is the only place in ``backend`` that reads the environment.

A bad value — given or from the environment — raises :class:`~nmkane_core.errors.InputError`
naming the field (``Settings.max_rows``) or the variable (``NMKANE_MAX_ROWS``), the value and
what is allowed; several bad values are named at once.  ``nmkane serve`` prints it on one line.

Each field's description is the documentation: the limits (fields marked ``service_limit``)
are served with theirs in ``GET /api/systems`` (``service_limits``,
``service_limit_descriptions``), and :func:`settings_table` writes the table of every
setting for the docs.  The defaults of ``max_steps`` and ``max_rows`` have their home in
the core, ``nmkane_core.schema.REST_DEFAULT_LIMITS``, which quotes them without importing
backend.
"""

from __future__ import annotations

import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, get_args

from pydantic import Field, ValidationError, ValidationInfo, field_validator, model_validator
from pydantic_settings import BaseSettings, NoDecode, SettingsConfigDict

from nmkane_core.errors import InputError
from nmkane_core.schema import REST_DEFAULT_LIMITS

from .store import POLICIES, StoreCap

__all__ = ["ENV_PREFIX", "LIMIT_DESCRIPTIONS", "Settings", "env_name", "settings_table"]

ENV_PREFIX = "NMKANE_"
MEGABYTE = 1_000_000
_STORE_MB = "NMKANE_MAX_STORE_MB"  # sets max_store_bytes, in megabytes


def _limit(*default: Any, description: str, json_schema_extra: dict | None = None, **constraints: Any) -> Any:
    """A field that is one of the service's limits (served in ``GET /api/systems``)."""
    extra = {"service_limit": True, **(json_schema_extra or {})}
    return Field(*default, description=description, json_schema_extra=extra, **constraints)


def _names(raw: Any) -> Any:
    """A comma-separated list (the environment's form) as a tuple of its non-empty items."""
    if isinstance(raw, str):
        return tuple(item.strip() for item in raw.split(",") if item.strip())
    return raw


Names = Annotated[tuple[str, ...], NoDecode]  # from the environment: comma-separated, not JSON


class Settings(BaseSettings):
    """Where the service keeps its runs, its limits and its exposure (see the module docstring)."""

    model_config = SettingsConfigDict(
        env_prefix=ENV_PREFIX,
        env_ignore_empty=True,  # NMKANE_MAX_ROWS= (empty) is the default
        populate_by_name=True,  # Settings(db_path=...) as well as NMKANE_DB
        str_strip_whitespace=True,
        extra="forbid",  # Settings(max_row=...) is a typo, not a setting
    )

    data_dir: Path = Field(Path("data"), description="directory of the embedded database (created if missing)")
    db_path: Path | None = Field(
        None,
        validation_alias="NMKANE_DB",
        description="the SQLite file of the runs; unset: data_dir/runs.sqlite3",
    )
    max_concurrent_runs: int = _limit(
        default_factory=lambda: os.cpu_count() or 2,
        ge=1,
        description="simulations running at once (worker threads; the compiled loops release the GIL, "
        "so they run in parallel)",
    )
    queue_limit: int = _limit(
        64,
        ge=0,
        description="runs admitted at once, running plus waiting; past it POST /api/runs answers 503 "
        "with a Retry-After header instead of queueing more",
    )
    max_steps: int = _limit(
        REST_DEFAULT_LIMITS["max_steps"],
        ge=1,
        description="fixed steps per run (t_final/dt); a request over it is refused with 422 before the "
        "run starts. Adaptive and scipy integrators are bounded by max_wall_time_s instead",
    )
    max_rows: int = _limit(
        REST_DEFAULT_LIMITS["max_rows"],
        ge=2,
        description="output rows per run; a fixed-step request over it is refused with 422 (raise `every`); "
        "an adaptive run stops when its output reaches it (status 'timeout', the message says why, "
        "results up to there kept)",
    )
    max_request_bytes: int = _limit(
        65_536, ge=1, description="size of a request body; a larger one is refused with 413"
    )
    max_wall_time_s: float = _limit(
        10.0,
        gt=0,
        allow_inf_nan=False,
        description="wall time per run in its worker, s (resolving the settings — a model's first use derives it "
        "— and integrating); a run past it ends with status 'timeout' and keeps what it computed so far",
    )
    cors_origins: Names = Field(
        (),
        json_schema_extra={"allowed": "origins such as https://class.example, comma-separated"},
        description="origins allowed by CORS (comma-separated); empty, the default: CORS stays closed",
    )
    max_stored_runs: int = _limit(
        100_000,
        ge=1,
        description="runs kept in the store; when full, a new run is refused with 507 (policy 'refuse', the "
        "default: a stored run is never deleted behind anyone's back) or the oldest runs are "
        "deleted to make room (policy 'evict-oldest', NMKANE_STORE_FULL); delete runs with "
        "DELETE /api/runs/{id} or `nmkane store prune`",
    )
    max_store_bytes: int = _limit(
        2_000 * MEGABYTE,
        ge=1,
        validation_alias=_STORE_MB,
        description="bytes of stored rows (settings, summary, compressed document), same policy as max_stored_runs",
    )
    store_full: str = Field(
        "refuse",
        json_schema_extra={"allowed": "one of " + ", ".join(POLICIES)},
        description="what a full store does with a new run: 'refuse' it (507) or 'evict-oldest' runs",
    )
    read_timeout_s: float = _limit(
        10.0,
        gt=0,
        allow_inf_nan=False,
        description="seconds a client has to send a request's head and its body; a slower one is cut off",
    )
    allowed_hosts: Names = Field(
        (),
        description="Host header names accepted besides the loopback names (comma-separated; "
        "`nmkane serve` adds the bound address and --allow-host names)",
    )
    token: str | None = Field(
        None,
        min_length=16,
        json_schema_extra={"secret": True, "allowed": "a string of at least 16 characters (`nmkane serve` makes one)"},
        description="a token every write must carry (Authorization: Bearer); unset: none asked for on "
        "loopback (`nmkane serve` makes one for another address)",
    )
    warm_kernels: bool = Field(True, description="load the compiled kernels when the app starts, so no request pays")
    max_sweep_runs: int = _limit(10_000, ge=1, description="runs per sweep (POST /api/sweeps); a larger one gets 422")
    max_sweeps: int = _limit(
        2,
        ge=1,
        description="sweeps admitted at once, running plus queued (they run one at a time); past it "
        "POST /api/sweeps answers 503 with a Retry-After header: the running sweep's remaining runs × "
        "the measured seconds per run ÷ sweep_workers",
    )
    sweep_workers: int | None = Field(
        None,
        ge=1,
        json_schema_extra={"allowed": "an integer ≥ 1 (at most max_concurrent_runs are used)"},
        description="run workers a sweep may use at once; unset: half of max_concurrent_runs, at least 1. "
        "A sweep also starts no run while an interactive run waits for a worker (runs first)",
    )
    dask_scheduler: str | None = Field(
        None,
        pattern=r"^(local(:[1-9][0-9]*)?|[a-z][a-z0-9+.-]*://\S+)$",
        json_schema_extra={"allowed": "tcp://HOST:PORT (a running Dask scheduler), local or local:N"},
        description="where REST sweeps run: unset, the service's worker pool; tcp://HOST:PORT, a running Dask "
        "scheduler (its workers need nmkane installed); local or local:N, a Dask cluster on this machine",
    )

    def __init__(self, **values: Any) -> None:
        try:
            super().__init__(**values)
        except ValidationError as e:
            raise _explained(e, given=values) from None

    # -- checks beyond types and ranges -------------------------------------------------
    @model_validator(mode="before")
    @classmethod
    def _environment_forms(cls, data: Any) -> Any:
        """A blank value is no value (``NMKANE_MAX_ROWS=" "`` is the default, as an empty one is);
        ``NMKANE_MAX_STORE_MB`` is in megabytes: as bytes (a bad value is left to the checks)."""
        if not isinstance(data, dict):
            return data
        data = {k: v for k, v in data.items() if not (isinstance(v, str) and not v.strip())}
        raw = data.get(_STORE_MB)
        if isinstance(raw, str) and raw.strip().isdigit():
            data[_STORE_MB] = int(raw) * MEGABYTE
        return data

    @field_validator("*", mode="before")
    @classmethod
    def _not_a_boolean(cls, value: Any, info: ValidationInfo) -> Any:
        """true/false is not a number (pydantic would read it as 1/0)."""
        if isinstance(value, bool) and cls.model_fields[str(info.field_name)].annotation in (int, float):
            raise ValueError("true/false is not a number")
        return value

    @field_validator("cors_origins", "allowed_hosts", mode="before")
    @classmethod
    def _split(cls, value: Any) -> Any:
        return _names(value)

    @field_validator("allowed_hosts")
    @classmethod
    def _lower_case(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        return tuple(name.lower() for name in value)

    @field_validator("cors_origins")
    @classmethod
    def _no_wildcard(cls, value: tuple[str, ...]) -> tuple[str, ...]:
        if "*" in value:
            raise ValueError("any origin ('*') is not accepted")
        return value

    @field_validator("store_full")
    @classmethod
    def _policy(cls, value: str) -> str:
        if value not in POLICIES:
            raise ValueError("not a store policy")
        return value

    # -- derived ------------------------------------------------------------------------
    @property
    def database(self) -> Path:
        """The SQLite file the runs are stored in."""
        return self.db_path if self.db_path is not None else self.data_dir / "runs.sqlite3"

    @property
    def sweep_share(self) -> int:
        """Run workers a sweep may use at once (``sweep_workers``, or half the workers, at least 1)."""
        share = self.sweep_workers if self.sweep_workers is not None else self.max_concurrent_runs // 2
        return max(1, min(share, self.max_concurrent_runs))

    @property
    def store_cap(self) -> StoreCap:
        return StoreCap(self.max_stored_runs, self.max_store_bytes, self.store_full)

    def limits(self) -> dict[str, int | float]:
        """The limits as served in ``GET /api/systems``."""
        return {name: getattr(self, name) for name in LIMIT_DESCRIPTIONS}


def _extra(field: str, key: str) -> Any:
    """What a field declares besides its type: ``service_limit``, ``secret``, ``allowed``."""
    extra = Settings.model_fields[field].json_schema_extra
    return extra.get(key) if isinstance(extra, dict) else None


#: What each limit means (served in ``GET /api/systems``), from the fields' descriptions.
LIMIT_DESCRIPTIONS: dict[str, str] = {
    name: info.description or "" for name, info in Settings.model_fields.items() if _extra(name, "service_limit")
}


def env_name(field: str) -> str:
    """The environment variable that sets ``field``."""
    alias = Settings.model_fields[field].validation_alias
    return alias if isinstance(alias, str) else ENV_PREFIX + field.upper()


# -- errors that say what to change -------------------------------------------------------
_BOUNDS = (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<"))
_REASONS = {
    "int_parsing": "not an integer",
    "int_from_float": "not an integer",
    "float_parsing": "not a number",
    "finite_number": "not a finite number",
    "bool_parsing": "not true or false",
    "greater_than": "out of range",
    "greater_than_equal": "out of range",
    "string_too_short": "too short",
    "string_pattern_mismatch": "unknown form",
    "extra_forbidden": "unknown field",
}
_KINDS: dict[Any, str] = {int: "an integer", float: "a finite number", bool: "true or false", Path: "a path"}


def _allowed(field: str) -> str:
    """What ``field`` accepts: as it declares (``allowed``), or from its type and bounds."""
    declared = _extra(field, "allowed")
    if declared:
        return str(declared)
    info = Settings.model_fields[field]
    bounds = [f"{sign} {getattr(m, key)}" for m in info.metadata for key, sign in _BOUNDS if hasattr(m, key)]
    kind = next((a for a in get_args(info.annotation) if a is not type(None)), info.annotation)  # X | None: X
    return " ".join([_KINDS.get(kind, "a string"), " and ".join(bounds)]).strip()


def _field_of(loc: tuple) -> str:
    """The field an error's location names (its name, or its environment variable's alias)."""
    head = str(loc[0]) if loc else ""
    return next((name for name, info in Settings.model_fields.items() if head == info.validation_alias), head)


def _item(err: Any, given: Mapping[str, Any]) -> InputError:
    """One validation error, naming ``Settings.<field>`` when the value was given and the
    environment variable when it came from there."""
    field = _field_of(err["loc"])
    if field not in Settings.model_fields:  # an unknown keyword argument
        return InputError(
            f"Settings.{field}", err.get("input"), "one of " + ", ".join(Settings.model_fields), "unknown"
        )
    alias = Settings.model_fields[field].validation_alias
    given_here = field in given or (isinstance(alias, str) and alias in given)
    where = f"Settings.{field}" if given_here else f"environment variable {env_name(field)}"
    value, allowed = err.get("input"), _allowed(field)
    if field == "max_store_bytes":  # given in bytes, or in megabytes in the environment
        allowed += " (bytes)" if given_here else " (megabytes)"
        value = value if given_here else os.environ.get(_STORE_MB, value)
    if _extra(field, "secret") and isinstance(value, str):
        value = f"({len(value)} characters, not shown)"
    return InputError(where, value, allowed, _REASONS.get(err["type"]) or re.sub(r"^Value error, ", "", err["msg"]))


def _explained(exc: ValidationError, given: Mapping[str, Any]) -> InputError:
    """The validation errors as one :class:`InputError` (``errors``: each one, when several)."""
    from nmkane_core.run.plan import raise_all

    try:
        raise_all([_item(err, given) for err in exc.errors()])
    except InputError as combined:
        return combined
    raise AssertionError("a ValidationError without errors") from exc


def _shown(field: str) -> str:
    """A field's default as the docs write it."""
    if field == "max_concurrent_runs":
        return "the number of CPU cores"
    if field == "sweep_workers":
        return "half of max_concurrent_runs"
    default = Settings.model_fields[field].get_default()
    if field == "max_store_bytes":
        return f"{default // MEGABYTE:,} MB"
    return "unset" if default in (None, ()) else f"`{default}`"


def settings_table() -> str:
    """Every setting as a Markdown table (for the docs): field, environment variable, default, meaning."""
    rows = ["| setting | environment variable | default | what it is |", "|---|---|---|---|"]
    for name, info in Settings.model_fields.items():
        rows.append(f"| `{name}` | `{env_name(name)}` | {_shown(name)} | {info.description} |")
    return "\n".join(rows)
