"""Links that reopen a setup (no browser: the session's own address and link reading; the
browser test checks the address bar and a fresh browser): the address carries the system
and every changed control under the REST names; opening one applies its values, refuses
bad ones beside their box and applies the rest; a reload keeps the setup."""

import pytest

from web.link import link_pairs, read_link
from web.session import MechanismApp


@pytest.fixture()
def app(module_server):
    a = MechanismApp(module_server, sync=True)
    yield a
    a.close()


def test_the_address_names_the_system_and_every_changed_control(app):
    assert app.link.pairs() == [("system", "appell-hamel")]  # the defaults: nothing else
    app.scene_choice.value = next(t for t, n in app.choices.items() if n == "rolling-disk")
    app.control("dt").text.value = "0.002"
    app.control("t_final").value = 7.0
    app.control("params.r").value = 0.25
    app.control("initial.u4").value = 0.5
    app.control("gamma").value = -10.0
    assert app.link.pairs() == [
        ("system", "rolling-disk"),
        ("dt", "0.002"),
        ("t_final", "7"),
        ("params.r", "0.25"),
        ("initial.u4", "0.5"),
        ("gamma", "-10"),
    ]
    assert app.link.written == app.link.pairs()  # written after the change (no page here: none to wait for)


def test_opening_a_link_builds_that_page_in_one_run(app):
    runs = len(app.sim_log)
    app.open_link("?system=rolling-disk&dt=0.002&t_final=7&params.r=0.25&initial.u4=0.5&gamma=-10")
    assert app.kind == "rolling-disk" and len(app.sim_log) == runs + 1
    s = app.sim_log[-1]
    assert (s["dt"], s["t_final"], s["gamma"]) == (0.002, 7.0, -10.0)
    assert s["params"]["r"] == 0.25 and s["initial"]["u4"] == 0.5
    assert app.traj.main.settings["params"]["r"] == 0.25
    assert "input refused" not in app.status.content


def test_a_links_bad_values_are_refused_beside_their_box_and_the_rest_applied(app):
    app.open_link("?system=appell-hamel&model=linear&compare=gamma0&dt=abc&gamma=-5&gamma2=1e9&t_final=12&foo=1")
    s = app.traj.request["settings"]  # the shown run's (the last simulated is the compare run)
    assert s["model"] == "linear" and s["t_final"] == 12.0 and s["dt"] == 0.01 and s["gamma"] == -5.0
    assert s["gamma2"] == 0.0
    assert list(app.traj.runs) == ["linear", "linear, Γ = 0"]  # compare=gamma0 is the run without Γ
    assert app.control("dt").message.visible and "is not a number" in app.control("dt").message.content
    assert "outside the allowed range" in app.control("gamma2").message.content
    assert "abc" in app.status.content and "1e9" in app.status.content
    app.open_link("?system=nope")
    assert "'nope' is not a system here" in app.status.content and app.kind == "appell-hamel"
    app.open_link("?compare=sideways&params.nope=2")
    assert "'sideways' is not one of off | nonlinear | linear" in app.status.content
    assert "params.nope is not a setting of this system" in app.status.content
    app.control("gamma").value = -6.0  # the next change: the link's refusals go
    assert "sideways" not in app.status.content


def test_scene_is_read_as_system_and_viser_parameters_are_left_alone(app):
    app.open_link("?hideViserLogo&scene=knife-edge&websocket=ws://x/&initial.u3=0")
    assert app.kind == "knife-edge" and app.sim_log[-1]["initial"]["u3"] == 0.0
    assert "input refused" not in app.status.content


def test_link_pairs_round_trip_through_read_link(app):
    view = app.system_view
    controls = tuple(app.sim_controls[view.kind])
    values = {c: c.default for c in controls}
    by = {c.field: c for c in controls}
    values[by["variant"]] = "linear"
    values[by["option.compare"]] = "Γ = 0"
    values[by["gamma"]] = -2.5
    pairs = link_pairs(view.system, view.core.option, values)
    assert ("model", "linear") in pairs and ("compare", "gamma0") in pairs and ("gamma", "-2.5") in pairs
    query = "?" + "&".join(f"{k}={v}" for k, v in pairs)
    back = read_link(query, controls, view.core.option)
    assert not back.refused
    assert back.values[by["variant"]] == "linear" and back.values[by["option.compare"]] == "Γ = 0"
    assert back.values[by["gamma"]] == "-2.5"  # numbers stay text: the box reads them as typed
