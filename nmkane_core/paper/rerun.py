"""Every run of the report, written so that a reader can make it again: the ``nmkane run``
command line, the REST request (``POST /api/runs``), and whether the REST service's default
limits (:data:`nmkane_core.schema.REST_DEFAULT_LIMITS`) must be raised for it."""

from __future__ import annotations

import json
import math

from ..schema import REST_DEFAULT_LIMITS
from .runs import RUN_LABELS, Runs

__all__ = ["cli_command", "rest_body", "rest_command", "run_doc"]

#: run settings that ``nmkane run`` takes as options, and the options' names
_CLI_OPTIONS = (
    ("model", "--model"),
    ("formulation", "--formulation"),
    ("gamma", "--gamma"),
    ("gamma1", "--gamma1"),
    ("gamma2", "--gamma2"),
    ("projection", "--projection"),
    ("integrator", "--integrator"),
    ("dt", "--dt"),
    ("t_final", "--t-final"),
    ("every", "--every"),
)

#: the run summary's fields the report quotes
_SUMMARY_FIELDS = (
    "status",
    "message",
    "steps",
    "wall_time_s",
    "max_abs_violation",
    "max_abs_energy_drift",
    "final_energy_drift",
)


def _fmt(v) -> str:
    if isinstance(v, float) and v.is_integer() and abs(v) < 1e15:
        return str(int(v))
    return str(v)


def cli_command(settings: dict, out: str | None = None) -> str | None:
    """``nmkane run ...`` for these settings (None when a setting has no CLI option)."""
    known = {"system"} | {k for k, _ in _CLI_OPTIONS}
    if set(settings) - known:
        return None
    parts = ["nmkane", "run", settings["system"]]
    for key, opt in _CLI_OPTIONS:
        v = settings.get(key)
        if v is None or (key == "projection" and v == "none"):
            continue
        parts += [opt, _fmt(v)]
    if out:
        parts += ["--out", out]
    return " ".join(parts)


def rest_body(settings: dict) -> str:
    """The JSON body of ``POST /api/runs`` for these settings."""
    return json.dumps(settings, ensure_ascii=False)


def rest_command(settings: dict) -> str:
    """A ``curl`` line that sends these settings to a local REST service."""
    return (
        f"curl -s -X POST http://127.0.0.1:8000/api/runs -H 'Content-Type: application/json' -d '{rest_body(settings)}'"
    )


def _rest_note(settings: dict) -> str | None:
    """What to raise when the run is larger than the REST service allows by default."""
    steps = math.ceil(settings["t_final"] / settings["dt"] - 1e-9)
    rows = steps // settings.get("every", 1) + 2
    max_steps, max_rows = REST_DEFAULT_LIMITS["max_steps"], REST_DEFAULT_LIMITS["max_rows"]
    if steps <= max_steps and rows <= max_rows:
        return None
    return (
        f"{steps:,} steps, {rows:,} output rows: above the REST service's default limits "
        f"({max_steps:,} steps, {max_rows:,} rows); start it with "
        f"NMKANE_MAX_STEPS={max(steps, max_steps)} NMKANE_MAX_ROWS={max(rows, max_rows)}"
    )


def run_doc(key: str, runs: Runs) -> dict:
    """The report's record of one run: label, settings, CLI and REST lines, summary or error."""
    settings = runs.settings[key]
    doc = {
        "label": RUN_LABELS.get(key, key),
        "settings": settings,
        "cli": cli_command(settings, out=f"{key}.json"),
        "rest": rest_command(settings),
    }
    note = _rest_note(settings)
    if note:
        doc["rest_note"] = note
    if key in runs.results:
        doc["summary"] = {k: v for k, v in runs.results[key].summary.items() if k in _SUMMARY_FIELDS}
    if key in runs.errors:
        doc["error"] = runs.errors[key]
    return doc
