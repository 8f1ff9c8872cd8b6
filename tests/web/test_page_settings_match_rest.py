"""One source for run settings (issue 43, item 7): the page builds the settings REST takes.

The settings the page starts each catalogue system with (:func:`web.generic.generic_controls`
read back by :func:`web.controls.settings_from`, as tests/systems/test_what_to_try.py reads
them) are valid :class:`~nmkane_core.schema.RunSettings` as they are, leave the tolerances at
the schema's defaults (the page once integrated at rtol = 1e-9, atol = 1e-10 where REST used
1e-10, 1e-12), and POST /api/runs runs them to the same numbers as ``simulate`` in this process.
"""

from __future__ import annotations

import json

import pytest
from fastapi.testclient import TestClient

from backend import Settings, create_app
from nmkane_core import simulate
from nmkane_core.run.registry import get_system, system_names
from nmkane_core.schema import RunSettings
from web.controls import settings_from
from web.generic import generic_controls

#: how long a run took and how its loop ran: the same code gives the same numbers, not the same clock
CLOCK = ("wall_time_s", "kernel_load_s", "kernel_tier")


#: a page choice where the tolerances count: the adaptive Kutta–Merson, over at most this long (s)
ADAPTIVE, HORIZON = "kutta-merson-adaptive", 1.0


def page(name: str, adaptive: bool = False) -> tuple[dict, dict]:
    """The settings of the page's first run of ``name`` (its default controls; ``adaptive``: with
    the integrator chooser on :data:`ADAPTIVE` and the final time cut to :data:`HORIZON`), and
    the REST body of the same choices: each control's value under its field's name."""
    core = get_system(name)
    values = {c: c.default for c in generic_controls(core, "page_")}
    for c in values:
        if adaptive and c.field == "integrator":
            values[c] = ADAPTIVE
        elif adaptive and c.field == "t_final":
            values[c] = min(float(c.default), HORIZON)  # type: ignore[arg-type]
    settings, _ = settings_from(core, values, lambda value: value)
    body: dict = {"system": name, "every": settings["every"]}
    for c, value in values.items():
        field, _, key = c.field.partition(".")
        field = core.option if field == "variant" else field
        if field in ("initial", "params"):
            body.setdefault(field, {})[key] = value
        elif field != "option":
            body[field] = value
    return settings, body


def numbers(summary: dict) -> dict:
    """A run summary without its timings, as JSON carries it."""
    return {k: v for k, v in json.loads(json.dumps(summary)).items() if k not in CLOCK}


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    settings = Settings(data_dir=tmp_path_factory.mktemp("store"), warm_kernels=False)
    with TestClient(base_url="http://localhost", app=create_app(settings)) as c:
        yield c


def rest(client, body: dict) -> dict:
    answer = client.post("/api/runs", json=body)
    assert answer.status_code == 201, answer.text
    return answer.json()


@pytest.mark.parametrize("name", system_names())
def test_the_page_leaves_the_tolerances_at_the_run_settings_defaults(name):
    """rtol and atol are no control of the page: it runs at RunSettings' defaults, as REST and the
    CLI do (the page once sent rtol = 1e-9, atol = 1e-10)."""
    fields = RunSettings.model_fields
    for adaptive in (False, True):
        s = RunSettings.model_validate(page(name, adaptive)[0])
        assert (s.rtol, s.atol) == (fields["rtol"].default, fields["atol"].default), name


@pytest.mark.parametrize("name", system_names())
def test_the_page_and_rest_run_the_same_settings_to_the_same_numbers(client, name):
    """The page's settings are RunSettings unchanged; POST /api/runs of them gives the resolved
    settings and summary numbers of ``simulate`` in this process, to the last digit; and REST given
    only the page's choices (each control's field and value) runs the page's run — with the
    adaptive integrator, where the tolerances count, and with the default one."""
    for adaptive in (True, False):
        settings, body = page(name, adaptive)
        assert RunSettings.model_validate(settings).model_dump(exclude_unset=True) == settings
        here = json.loads(simulate(settings, progress=False).document().model_dump_json(by_alias=True))
        there = rest(client, settings)
        assert there["settings"] == here["settings"], adaptive
        assert numbers(there["summary"]) == numbers(here["summary"]), adaptive
        chosen = rest(client, body)
        assert numbers(chosen["summary"]) == numbers(here["summary"]), adaptive
        assert chosen["settings"] == there["settings"], adaptive
