"""The server: viser, one :class:`~web.session.MechanismApp` per connected browser, and one
animation thread that poses every session's scene at ``FPS`` and refreshes plot markers,
the time scrubber and readouts at ``REFRESH_HZ``.

:func:`launch_app` (the composition point's entry, ``web.server:launch_app``) and
:func:`launch` start it in the background; :func:`main` blocks (``python -m web``).

Connections pass a gate (:meth:`WebApp._gate`) before anything is sent to them: the
websocket handshake must name an allowed host (``Host``: loopback names, the bound address,
``allowed_hosts``, or an IP address — DNS rebinding needs a name), come from a page of this
server (``Origin``, when a browser sends one), carry the token when one is set (the printed
URL passes it to viser's client as ``?websocket=ws://…/?token=…``), and find a free seat
(``max_sessions``, ``NMKANE_MAX_SESSIONS``, default 40).  A turned-away browser is closed
with code 1002, which viser's client shows as a "Connection rejected" notice with the
reason; it retries every second while its tab has focus, and gets in when a seat is free.
(viser 1.1 has no public hook for this: the gate is registered on its websocket server and
reads the handshake there, through :mod:`web.viser_compat`.)

viser's HTTP server (the page and its scripts, on the same port) answers the same Host
allow-list: a request naming another host gets 403 (:meth:`WebApp._guard_http`, through
:func:`web.viser_compat.guard_http`).

Capacity: the animation thread poses every session at ``FPS``, or less with many sessions:
it works at most ``DUTY`` of its time (a frame that took w seconds of the thread's CPU
time is followed by at least w·(1/DUTY − 1) of rest), so however many browsers are connected the animation
leaves CPU for the REST API and the websocket sends (measured, see README "Classroom");
plot markers, the scrubber and readouts follow at
``REFRESH_HZ``; a session whose browser has not yet taken its previous frame skips frames
(its animation time is carried over, so it plays at the right speed, just less smoothly),
and :mod:`web.fastpath` keeps the per-frame work of viser's handles small.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import threading
import time
from urllib.parse import parse_qs, quote, urlsplit

import viser

from nmkane_core.access import HostAllowList, host_name, token_matches
from nmkane_core.heap import malloc_trim
from nmkane_core.run.registry import get_system
from nmkane_core.run.simulate import simulate as core_simulate

from . import fastpath
from . import matrices as mx
from . import viser_compat as compat
from .generic import warm_systems
from .session import MechanismApp, racing_a_leave

FPS = 40.0  # poses sent per second at most (the target is ≥ 30 for a few browsers, ≥ 20 for a classroom)
DUTY = 0.6  # at most this share of the animation thread's time is work: many sessions lower the rate
REFRESH_HZ = 4.0  # plot markers, scrubber, readouts
MAX_SESSIONS = 40  # browsers served at once by default (NMKANE_MAX_SESSIONS)
TRIM_DELAY_S = 2.0  # after a session closes, return its memory this much later
REJECTED = 1002  # close code viser's client shows as "Connection rejected: <reason>"


def _reachable(host: str) -> str:
    """An address browsers can use for a server bound to ``host`` (a wildcard bind: this
    machine's address on its default route, found without sending anything)."""
    if host not in ("0.0.0.0", "::", ""):
        return host
    try:
        import socket

        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect(("192.0.2.1", 9))  # TEST-NET-1: a route lookup, no packet sent
            return probe.getsockname()[0]
    except OSError:
        return "127.0.0.1"


_trim_lock = threading.Lock()


def _release_memory() -> None:
    """Give the memory a closed session freed back to the system.  Python frees a session's
    objects, but glibc keeps freed heap pages in its per-thread arenas (every session's
    threads allocate): measured, 25 sessions opened and closed left the process 25–30 MB
    larger per cycle, and ``malloc_trim(0)`` returned it all."""
    if malloc_trim is not None and _trim_lock.acquire(blocking=False):
        try:
            gc.collect()  # a session's objects are in reference cycles: free them first
            malloc_trim(0)
        finally:
            _trim_lock.release()


def _backlog(client) -> int:
    """Messages queued for a browser that its connection has not taken yet (−1: closed; see
    :func:`web.viser_compat.backlog`)."""
    return compat.backlog(client)


def _max_sessions_default() -> int:
    raw = os.environ.get("NMKANE_MAX_SESSIONS", "").strip()
    if not raw:
        return MAX_SESSIONS
    if not raw.isdigit() or int(raw) < 1:
        raise ValueError(f"environment variable NMKANE_MAX_SESSIONS={raw!r}: an integer ≥ 1 is needed")
    return int(raw)


class WebApp:
    """The viser server, one :class:`MechanismApp` per connected browser, one animation thread.

    The handle ``launch()`` returns: ``.port`` (the port actually bound) and ``.stop()``.
    """

    def __init__(
        self,
        host: str = "127.0.0.1",
        port: int = 8080,
        simulate=core_simulate,
        *,
        token: str | None = None,
        allowed_hosts=(),
        max_sessions: int | None = None,
        scene: str | None = None,
    ):
        """``token``: asked for on every connection (None: none); ``allowed_hosts``: host names
        accepted besides the loopback names and ``host``; ``max_sessions``: browsers served at once;
        ``scene``: the system new browsers open on."""
        self.token = token
        self.max_sessions = _max_sessions_default() if max_sessions is None else int(max_sessions)
        if self.max_sessions < 1:
            raise ValueError(f"max_sessions = {max_sessions!r}: an integer ≥ 1 is needed")
        self.allowed_hosts = HostAllowList.of(host, allowed_hosts)  # the REST API's rule (nmkane_core.access)
        self._admitted: set[int] = set()  # connections past the gate (sessions or about to be)
        self._trim_due: float | None = None  # when to return closed sessions' memory (monotonic)
        self.rejected = 0
        fastpath.install()  # the per-frame pose updates without viser's numpy overhead
        self.server = viser.ViserServer(host=host, port=port, label="nmkane", verbose=False)
        compat.on_handshake(self.server, self._gate, self._ungate)  # the gate runs before anything is sent
        self.server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
        self.server.scene.set_up_direction("+z")
        self.scene = scene  # the system new browsers open on (None: the first)
        self.port = self.server.get_port()
        self._guard_http()
        self.host = host
        self.sessions: dict[int, MechanismApp] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._simulate = simulate
        self.frame_times: list[float] = []
        self.frame_work_s: list[float] = []
        self._owed: dict[int, float] = {}  # animation time owed to sessions whose frames were skipped
        self.skipped = 0  # session frames skipped (browser not keeping up)
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)
        self._warm_thread = threading.Thread(target=warm, args=(self._stop,), daemon=True, name="nmkane-warm")
        self._warm_thread.start()
        self._anim = threading.Thread(target=self._animate, daemon=True, name="nmkane-animate")
        self._anim.start()

    @property
    def url(self) -> str:
        """The page's URL (with the token for viser's websocket when one is set)."""
        host = _reachable(self.host)
        host = f"[{host}]" if ":" in host else host
        base = f"http://{host}:{self.port}/"
        if not self.token:
            return base
        return base + "?websocket=" + quote(f"ws://{host}:{self.port}/?token={self.token}", safe="")

    def _refusal(self, request) -> str | None:
        """Why a websocket handshake is turned away (None: admitted); checks Host, Origin, token."""
        headers = request.headers
        host = headers.get("Host", "")
        if not self.allowed_hosts.admits(host):
            return f"host {host_name(host)[:40]!r} not allowed (nmkane serve --allow-host)"
        origin = headers.get("Origin")
        if origin is not None and urlsplit(origin).netloc.lower() != host.lower():
            return "cross-origin connection refused"
        if self.token is not None:
            given = parse_qs(urlsplit(request.path).query).get("token", [""])[0]
            if not token_matches(given, self.token):
                return "access token missing or wrong: open the URL nmkane serve printed"
        return None

    def _guard_http(self) -> None:
        """Make viser's HTTP server (the page) answer 403 to a Host not allowed (see the module
        docstring); RuntimeError if viser's server cannot be found (a viser other than 1.1)."""

        def refusal(request) -> str | None:
            host = request.headers.get("Host", "")
            if self.allowed_hosts.admits(host):
                return None
            self.rejected += 1
            return f"host {host_name(host)[:40]!r} not allowed (nmkane serve --allow-host)"

        compat.guard_http(self.port, refusal)

    async def _gate(self, conn) -> None:
        """On the websocket server's event loop, before any message is sent to the connection."""
        ws = compat.handshake(self.server, conn.client_id)
        if ws is None:
            return
        reason = self._refusal(ws.request)
        if reason is None:
            with self._lock:
                if len(self._admitted) >= self.max_sessions:
                    reason = (
                        f"nmkane is full ({self.max_sessions} browsers); this page retries and gets in when one leaves"
                    )
                else:
                    self._admitted.add(conn.client_id)
        if reason is not None:
            self.rejected += 1
            await ws.close(REJECTED, reason[:120])

    async def _ungate(self, conn) -> None:
        with self._lock:
            self._admitted.discard(conn.client_id)

    def connected(self, client_id: int) -> bool:
        """The browser is still connected: viser lists it (it drops it before the disconnect
        callbacks run) and its connection is open (viser closes the connection first, then
        drops the client: in between, what is sent to it is never delivered)."""
        client = self.server.get_clients().get(client_id)
        return client is not None and _backlog(client) >= 0

    def _connect(self, client: viser.ClientHandle) -> None:
        cid = client.client_id
        with racing_a_leave(client):  # the browser may leave while its page is built
            session = MechanismApp(
                client, simulate=self._simulate, connected=lambda: self.connected(cid), scene=self.scene
            )
        with self._lock:  # viser pops a leaving client before its disconnect callbacks run
            if self.connected(cid):
                self.sessions[cid] = session
                return
        # the browser left while its page was built: its disconnect callback found no session
        session.close()
        self._trim_due = time.monotonic() + TRIM_DELAY_S

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            session = self.sessions.pop(client.client_id, None)
        self._owed.pop(client.client_id, None)
        if session is not None:
            session.close()
            del session
            self._trim_due = time.monotonic() + TRIM_DELAY_S  # once its threads have ended too

    def _tick_sessions(self, dt_wall: float, refresh: bool) -> None:
        """One frame of every session (a session whose browser left skips itself)."""
        with self._lock:
            sessions = list(self.sessions.items())
        for cid, s in sessions:
            owed = self._owed.pop(cid, 0.0) + dt_wall
            backlog = _backlog(s.client)
            if backlog < 0:  # closed: its session is about to be dropped
                continue
            if backlog > 0:  # its browser has not taken the last frame yet: skip this one
                self._owed[cid] = min(owed, 0.25)
                self.skipped += 1
                continue
            with contextlib.suppress(Exception):  # a client gone mid-frame: skip it this frame
                s.tick(owed, refresh)

    def _animate(self) -> None:
        period = 1.0 / FPS
        last = last_refresh = next_frame = time.perf_counter()
        while not self._stop.is_set():
            t0, cpu0 = time.perf_counter(), time.thread_time()
            dt_wall, last = min(t0 - last, 0.25), t0
            refresh = t0 - last_refresh >= 1.0 / REFRESH_HZ
            if refresh:
                last_refresh = t0
            self._tick_sessions(dt_wall, refresh)  # its locals (the sessions) go when it returns
            if self._trim_due is not None and time.monotonic() >= self._trim_due:
                self._trim_due = None
                _release_memory()
            self.frame_times.append(t0)
            self.frame_work_s.append(time.perf_counter() - t0)
            del self.frame_times[:-400], self.frame_work_s[:-400]
            now = time.perf_counter()
            # CPU time, not wall time: on a busy machine waiting for a core is no reason to slow down
            rest = (time.thread_time() - cpu0) * (1.0 / DUTY - 1.0)  # many sessions: a lower rate
            next_frame = max(next_frame + period, now + rest)  # a fixed rate, no drift, when there is time
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


def warm(stop: threading.Event | None = None) -> None:
    """Load every system's compiled kernels (a short run of each: derived and compiled on a first
    start), compile its visuals, and derive the
    matrices panels before anyone waits.  Ends after the system under way once ``stop`` is
    set (the app stopped: nobody is left to wait for the rest)."""
    stopped = stop.is_set if stop is not None else (lambda: False)
    first = warm_systems(stopped=stopped)
    rest = []
    for name, default in first:
        with contextlib.suppress(Exception):
            rest += [(name, v) for v in get_system(name).variants if v != default]
    for key in first + rest:  # every system's first model, then the others
        if stopped():
            return
        with contextlib.suppress(Exception):
            mx.panel(*key)


def launch(host: str = "127.0.0.1", port: int = 8080, scene: str | None = None, **options) -> WebApp:
    """Start the web app in the background; returns a handle with ``.stop()`` and ``.port``.
    ``scene``: the registered system new browsers open on (default: the first); ``options``:
    ``token``, ``allowed_hosts``, ``max_sessions`` (see :class:`WebApp`)."""
    if scene is not None:
        get_system(scene, "scene")  # unknown: InputError naming the choices
    return WebApp(host=host, port=port, scene=scene, **options)


def launch_app(host: str, port: int, **options) -> WebApp:
    """The composition point's entry (``nmkane.apps``): start in the background and return a
    handle with ``.port`` (the bound port), ``.url`` and ``.stop()``; options it knows
    (``scene``, ``token``, ``allowed_hosts``, ``max_sessions``) are passed on, others are ignored."""
    known = {k: v for k, v in options.items() if k in ("scene", "token", "allowed_hosts", "max_sessions")}
    return launch(host, port, **known)


def main() -> None:
    """``python -m web``: serve until Ctrl-C or SIGTERM."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m web", description="nmkane 3D web app (viser)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8080)
    ap.add_argument("--scene", default=None, help="the system new browsers open on")
    args = ap.parse_args()
    stopping: list[int] = []  # no lock in a signal handler (see backend.serve)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    app = launch(args.host, args.port, scene=args.scene)
    print(f"nmkane 3D web app {app.url}  (Ctrl-C to stop)", flush=True)
    try:
        while not stopping:
            time.sleep(0.2)
    finally:
        app.stop()
