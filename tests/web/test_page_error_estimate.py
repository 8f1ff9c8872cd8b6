"""The page's controls for the error estimate and the projection near singular positions map to
run settings, and the status line shows the estimate (issue 45 item 5, issue 42 item 2)."""

import time
from types import SimpleNamespace

from nmkane_core import get_system, simulate
from web.controls import settings_from
from web.generic import generic_controls
from web.panel import status_text


def _controls(name: str) -> dict:
    return {c.field: c for c in generic_controls(get_system(name), "p_")}


def test_the_checkboxes_are_run_settings_and_the_status_line_shows_the_estimate():
    fields = _controls("sliding-particle")
    assert fields["error_estimate"].kind == "checkbox" and fields["error_estimate"].default is False
    assert fields["singular_projection"].default is True  # a constrained model
    values = {c: c.default for c in fields.values()}
    values[fields["error_estimate"]] = True
    settings, _ = settings_from(get_system("sliding-particle"), values, lambda v: v)
    assert settings["error_estimate"] is True and settings["singular_projection"] is True
    run = simulate({**settings, "t_final": 2.0}, progress=False)
    est = run.summary["error_estimate"]
    assert est["max_abs"] and est["method"] == "half step"
    traj = SimpleNamespace(
        runs={"nonminimal": run}, request={"settings": settings}, seq=1, t_request=time.perf_counter(), compute_s=0.0
    )
    text = status_text(traj, 1)
    largest = max(est["max_abs"].values())
    assert f"estimated global error ≤ {largest:.1e}" in text and "half step" in text
