"""Bad values over the websocket and browsers that leave, through viser's real message path:
a bare websocket client that speaks viser's protocol (msgpack messages) stands in for the
browser, so no Chromium is needed."""

import math
import threading
import time
import warnings

import msgspec
import pytest
import viser
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from nmkane_core.run.simulate import simulate as core_simulate
from web.app import WebApp, dt_of


class RawClient:
    """A websocket client of the viser server: it drains what the server sends and can send
    a GUI update, as the page does when a slider moves."""

    def __init__(self, port: int):
        self.ws = connect(f"ws://127.0.0.1:{port}", subprotocols=[f"viser-v{viser.__version__}"], max_size=None)
        threading.Thread(target=self._drain, daemon=True).start()
        self.send(
            {
                "type": "ViewerCameraMessage",
                "wxyz": (1.0, 0.0, 0.0, 0.0),
                "position": (-20.0, 35.0, 20.0),
                "fov": 1.0,
                "near": 0.01,
                "far": 1000.0,
                "image_height": 900,
                "image_width": 1400,
                "look_at": (0.0, 0.0, 5.0),
                "up_direction": (0.0, 0.0, 1.0),
            }
        )  # viser: now connected

    def _drain(self) -> None:
        try:
            while True:
                self.ws.recv()
        except (ConnectionClosed, OSError):  # closed by the test or the server
            pass

    def send(self, msg: dict) -> None:
        self.ws.send(msgspec.msgpack.encode(msg))

    def set_value(self, handle, value) -> None:
        self.send({"type": "GuiUpdateMessage", "uuid": handle._impl.uuid, "updates": {"value": value}})

    def close(self) -> None:
        self.ws.close()


def _until(predicate, timeout: float = 10.0) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if predicate():
            return True
        time.sleep(0.02)
    return predicate()


@pytest.fixture()
def served():
    app = WebApp(port=0)
    client = RawClient(app.port)
    session = app.wait_for_session()
    assert session.wait_idle(90)
    yield app, client, session
    client.close()
    app.stop()


def test_non_finite_or_out_of_range_slider_values_are_refused(served):
    _, client, s = served
    runs = len(s.sim_log)
    h_dt, h_gamma = s.control("log_dt"), s.control("gamma")
    log_dt, gamma = h_dt.value, h_gamma.value
    for handle, bad, good in (
        (h_dt, math.nan, log_dt),
        (h_dt, math.inf, log_dt),
        (h_gamma, -math.inf, gamma),
        (h_gamma, 1e6, gamma),
    ):
        client.set_value(handle, bad)
        assert _until(lambda b=bad: repr(b) in s.status.content), s.status.content  # not a stale panel
        assert "input refused" in s.status.content and handle.label in s.status.content
        assert _until(lambda h=handle, g=good: h.value == g)  # back to the last good value
    assert s.wait_idle(10) and len(s.sim_log) == runs  # no run with a bad value

    client.set_value(s.speed, math.nan)  # playback sliders too
    assert _until(lambda: s.speed.value == 1.0 and "Speed" in s.status.content)
    s.tick(0.1, refresh=True)
    assert math.isfinite(s.t_now)

    client.set_value(h_dt, -2.5)  # a good value still runs
    assert _until(lambda: "Δt = 0.0032 s · update" in s.status.content, 30), s.status.content
    assert s.traj.main.settings["dt"] == dt_of(-2.5) == 0.0032


class SlowDisconnect(WebApp):
    """The app's disconnect callback runs late (viser's thread pool is busy): the browser
    has gone for viser before the session knows."""

    def _disconnect(self, client) -> None:
        time.sleep(0.5)
        super()._disconnect(client)


def test_nothing_is_sent_to_a_browser_that_left_mid_run():
    app = None

    def late(settings, **kw):  # a run that ends after the browser left
        run = core_simulate(settings, **kw)
        if settings.get("gamma") == -2.0:
            _until(lambda: not app.server.get_clients(), 10)
        return run

    app = SlowDisconnect(port=0, simulate=late)
    try:
        client = RawClient(app.port)
        session = app.wait_for_session()
        assert session.wait_idle(90)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            client.set_value(session.control("gamma"), -2.0)
            assert _until(lambda: session.sim_log[-1].get("gamma") == -2.0)
            client.close()
            assert _until(lambda: not app.sessions, 10)
            assert session.wait_idle(10)
            last = app.frame_times[-1]  # frames go on: 20 more animation frames
            assert _until(lambda: sum(t > last for t in app.frame_times[-40:]) >= 20, 30)
        # the late run's scene (install: positions, shapes) must not be sent; a GUI text update racing
        # the disconnect inside viser (it closes the socket before dropping the client) is not ours
        closed = [
            str(w.message)
            for w in caught
            if "closed connection" in str(w.message) and "GuiUpdateMessage" not in str(w.message)
        ]
        assert not closed, closed
        assert session.traj.main.settings["gamma"] == 0.0  # the late run was not installed
    finally:
        app.stop()


def test_launch_app_is_the_composition_points_entry():
    from web.app import launch_app

    handle = launch_app("127.0.0.1", 0, title="ignored", reload=True)  # unknown options are ignored
    try:
        assert handle.port > 0
        import urllib.request

        html = urllib.request.urlopen(f"http://127.0.0.1:{handle.port}/", timeout=10).read()
        assert b"<html" in html[:2000].lower()
    finally:
        handle.stop()
