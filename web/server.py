"""The server: viser, one :class:`~web.session.MechanismApp` per connected browser, and one
animation thread that poses every session's scene at ``FPS`` and refreshes plot markers,
the time scrubber and readouts at ``REFRESH_HZ``.

:func:`launch_app` (the composition point's entry, ``web.server:launch_app``) and
:func:`launch` start it in the background; :func:`main` blocks (``python -m web``).
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time

import viser

from nmkane_core.simulate import simulate as core_simulate
from nmkane_core.registry import get_system

from . import matrices as mx
from .generic import warm_systems
from .session import MechanismApp
from .systems import VIEWS

FPS = 40.0                    # poses sent per second (the target is ≥ 30)
REFRESH_HZ = 4.0              # plot markers, scrubber, readouts


class WebApp:
    """The viser server, one :class:`MechanismApp` per connected browser, one animation thread.

    The handle ``launch()`` returns: ``.port`` (the port actually bound) and ``.stop()``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, simulate=core_simulate, scene: str | None = None):
        self.server = viser.ViserServer(host=host, port=port, label="nmkane", verbose=False)
        self.server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
        self.server.scene.set_up_direction("+z")
        self.scene = scene                           # the system new browsers open on (None: the first)
        preset = VIEWS[0].initial_camera() if scene in (None, VIEWS[0].system) else None   # the camera's start
        if preset is not None:
            self.server.initial_camera.look_at, self.server.initial_camera.position = preset
        self.port = self.server.get_port()
        self.host = host
        self.sessions: dict[int, MechanismApp] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._simulate = simulate
        self.frame_times: list[float] = []
        self.frame_work_s: list[float] = []
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)
        self._warm_thread = threading.Thread(target=warm, daemon=True, name="nmkane-warm")
        self._warm_thread.start()
        self._anim = threading.Thread(target=self._animate, daemon=True, name="nmkane-animate")
        self._anim.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def connected(self, client_id: int) -> bool:
        """The browser is still connected (viser drops it before the disconnect callbacks run)."""
        return client_id in self.server.get_clients()

    def _connect(self, client: viser.ClientHandle) -> None:
        cid = client.client_id
        session = MechanismApp(client, simulate=self._simulate, connected=lambda: self.connected(cid),
                               scene=self.scene)
        with self._lock:
            self.sessions[cid] = session

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.close()

    def _animate(self) -> None:
        period = 1.0 / FPS
        last = last_refresh = next_frame = time.perf_counter()
        while not self._stop.is_set():
            t0 = time.perf_counter()
            dt_wall, last = min(t0 - last, 0.25), t0
            refresh = t0 - last_refresh >= 1.0 / REFRESH_HZ
            if refresh:
                last_refresh = t0
            with self._lock:
                sessions = list(self.sessions.values())
            for s in sessions:                     # a session whose browser left skips itself
                try:
                    s.tick(dt_wall, refresh)
                except Exception:                  # a client gone mid-frame: skip it this frame
                    pass
            self.frame_times.append(t0)
            self.frame_work_s.append(time.perf_counter() - t0)
            del self.frame_times[:-400], self.frame_work_s[:-400]
            next_frame = max(next_frame + period, time.perf_counter())   # fixed rate, no drift
            self._stop.wait(max(0.0, next_frame - time.perf_counter()))

    def fps(self, last: int = 120) -> float:
        """Frames per second of the animation thread over the last frames."""
        ts = self.frame_times[-last:]
        return (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 2 and ts[-1] > ts[0] else 0.0

    def wait_for_session(self, timeout: float = 30.0) -> MechanismApp:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                if self.sessions:
                    return next(iter(self.sessions.values()))
            time.sleep(0.05)
        raise TimeoutError("no browser connected")

    def stop(self) -> None:
        self._stop.set()
        self._anim.join(2)
        with self._lock:
            sessions, self.sessions = list(self.sessions.values()), {}
        for s in sessions:
            s.close()
        mx.shutdown()
        self.server.stop()


def warm() -> None:
    """Load every view's compiled kernels and their loops (numba loads machine code at a
    function's first call: a short run does it) and derive the matrices panels before
    anyone waits."""
    first, rest = [], []
    for view in VIEWS:
        system = get_system(view.system)
        for v in system.variants:
            with contextlib.suppress(Exception):
                system.kernel(v)
        for v in system.variants:
            with contextlib.suppress(Exception):
                core_simulate({"system": system.name, system.option: v, "t_final": 0.05}, progress=False)
        shown = view.matrices_variants()
        first.append((system.name, shown[0]))
        rest += [(system.name, v) for v in shown[1:]]
    others = warm_systems(skip={view.system for view in VIEWS})     # every other system's kernels, visuals
    for key in first + others + rest:    # every system's first model, then the others
        with contextlib.suppress(Exception):
            mx.panel(*key)


def launch(host: str = "127.0.0.1", port: int = 8080, scene: str | None = None) -> WebApp:
    """Start the web app in the background; returns a handle with ``.stop()`` and ``.port``.
    ``scene``: the registered system new browsers open on (default: the first)."""
    if scene is not None:
        get_system(scene, "scene")                   # unknown: InputError naming the choices
    return WebApp(host=host, port=port, scene=scene)


def launch_app(host: str, port: int, **options) -> WebApp:
    """The composition point's entry (``nmkane.apps``): start in the background and return a
    handle with ``.port`` (the bound port) and ``.stop()``.  Options: ``scene`` (the system new
    browsers open on); unknown options are ignored."""
    return launch(host, port, scene=options.get("scene"))


def main() -> None:
    """``python -m web``: serve until Ctrl-C or SIGTERM."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m web", description="nmkane 3D web app (viser)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--scene", default=None, help="the system new browsers open on")
    args = ap.parse_args()
    stopping: list[int] = []               # no lock in a signal handler (see backend.serve)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    app = launch(args.host, args.port, scene=args.scene)
    print(f"nmkane 3D web app {app.url}  (Ctrl-C to stop)", flush=True)
    try:
        while not stopping:
            time.sleep(0.2)
    finally:
        app.stop()
