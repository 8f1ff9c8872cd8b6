"""viser through one door: every use the web app makes of viser's private API.

viser 1.1 has public handles for scenes, GUIs and cameras, but none for what a classroom
server needs around them; the web app reaches behind them only here, each use behind a
named function.  Checked against **viser 1.1.1** (:data:`CHECKED`), and pinned in
``pyproject.toml`` to :data:`PINNED` (``viser>=1.1.1,<1.2``: its patch releases, not the
next minor one); ``tests/web/test_viser_compat.py`` exercises every function below against
the installed viser (a renamed internal fails there, naming the function), and checks that
no other module of ``web/`` touches viser's private API.

Python side — what, and why:

* ``ClientHandle._websock_connection`` (one browser's connection) and its message buffer
  (``infra.AsyncMessageBuffer``):

  - :func:`dead_writes_allowed` — ``buffer.sanctioned_dead_writes()``: writes that may race a
    browser leaving (a page being built, a run installed, a frame) are dropped without
    viser's "Queued … on a closed connection" warning;
  - :func:`backlog` — ``buffer.generator_cursors``, ``message_counter``, ``done``: how many
    messages the browser has not taken yet (the animation skips a frame for a browser that
    is behind; −1: the connection is closed);
  - :func:`queue` / :func:`run_javascript` — ``connection.queue_message`` and
    ``_messages.RunJavascriptMessage`` (the message viser itself uses to load plotly): the
    page's own scripts (:mod:`web.page`);
  - :func:`whole_windows` — ``buffer.max_window_size``: viser sends at most 128 messages per
    websocket message; a system's first run (its nodes made, up to ~120 messages, more with
    ghosts) is sent in one, so the page never draws half of it.

* ``GuiHandle._impl.uuid`` (:func:`gui_uuid`): the id the page's scripts answer to.
* ``CameraHandle._state`` and ``_messages.SetCameraPositionMessage`` /
  ``SetCameraLookAtMessage`` (:func:`camera_pose`, :func:`send_camera`): a following camera
  sends the two messages the setters send without their orientation math (half a frame's
  CPU, measured).
* ``viser._scene_handles._set_pose_vector`` (:func:`replace_pose_setter`): every pose write
  goes through it; :mod:`web.fastpath` puts a plain-Python equivalent in its place.
* ``ViserServer._websock_server`` (:func:`on_handshake`, :func:`handshake`): the websocket
  server's own connect/disconnect callbacks (before anything is sent to the browser) and the
  handshake of a connection (``_live_connections``): the gate of :mod:`web.server`.
* viser's HTTP server, a ``websockets.asyncio.server.Server`` found among the process's
  objects by its port (:func:`guard_http`): the page answers 403 to a Host not allowed.

Page side — viser's client, ``window.__viserMutable`` (what viser exposes for its own
end-to-end tests):

* ``sendMessage`` with a ``GuiUpdateMessage`` (:func:`page_send`): a page script answers
  through a hidden text box, exactly what typing in it sends;
* ``messageQueue``, ``drainMessageQueue``, ``getRenderRequestState`` (:data:`WHOLE_FRAMES`):
  **each frame whole**.  The client applies a batch's node poses (``position``, ``wxyz``) in
  the frame that drains it, but props (a line's ``points``, an arrow's ``scale``, a label's
  text) only when React commits, after that frame is drawn: every frame showed a bar where
  it had been a frame earlier, away from the bob at its end (measured, a pendulum in
  headless Chromium: 30 of 30 frames off, by up to 1.1 m).  The script drains each batch as
  it arrives, so React commits the props before the next frame, which draws them with the
  poses of the same batch.  The live page runs it through :func:`run_javascript`, the export carries it
  (:func:`whole_frames_script`).

Left outside (the client's DOM, not its API): the CSS classes of Mantine and uPlot and the
playback bar's ``[role=slider]`` that :mod:`web.numbers`, :mod:`web.page`,
:mod:`web.export_panel` and :mod:`web.export_gif` style or read.
"""

from __future__ import annotations

import contextlib
import inspect
import json
import time
from collections.abc import Callable
from typing import Any

import numpy as np

CHECKED = "1.1.1"  # the viser this module was checked against
PINNED = ">=1.1.1,<1.2"  # pyproject.toml's requirement (both extras that install viser)
WINDOW = 1024  # messages per websocket message at least (viser's default: 128)


# ------------------------------------------------------------------ one browser's connection
def connection(client) -> Any | None:
    """The browser's websocket connection (viser's ``WebsockClientConnection``), or None
    (``client`` None: a test's shared server)."""
    return getattr(client, "_websock_connection", None)


def _buffer(client):
    conn = connection(client)
    return None if conn is None else conn.get_message_buffer()


def dead_writes_allowed(client):
    """The scope of writes that may race the browser's leaving: messages queued there after
    viser closed the connection are dropped with it, and viser's warning about them is
    silenced (it is kept for every other write).  ``client`` None (a test's shared server)
    or a viser without the scope: no scope."""
    try:
        return _buffer(client).sanctioned_dead_writes()
    except AttributeError:
        return contextlib.nullcontext()


def backlog(client) -> int:
    """Messages queued for a browser that its connection has not taken yet (0 for a test's
    shared server, or when viser's internals differ; −1 once the connection is closed:
    nothing sent to it would be delivered)."""
    conn: Any = connection(client)
    try:
        buf = conn.get_message_buffer()
        cursor = buf.generator_cursors.get(conn.client_id)
    except AttributeError:
        return 0
    if buf.done:
        return -1
    return 0 if cursor is None else max(0, buf.message_counter - 1 - cursor)


def queue(client) -> Callable[[Any], None] | None:
    """The browser's message queue (``connection.queue_message``), or None: no browser, or a
    viser without ``RunJavascriptMessage``."""
    try:
        from viser import _messages

        _messages.RunJavascriptMessage  # noqa: B018
    except (ImportError, AttributeError):
        return None
    return getattr(connection(client), "queue_message", None)


def run_javascript(client, source: str) -> bool:
    """Run ``source`` in the browser's page (viser's client evaluates it); False when there is
    no page to run it in."""
    send = queue(client)
    if send is None:
        return False
    from viser import _messages

    send(_messages.RunJavascriptMessage(source=source))
    return True


def whole_windows(client, at_least: int = WINDOW) -> bool:
    """Let viser send up to ``at_least`` messages to this browser in one websocket message
    (an atomic batch of fewer arrives whole); False without a browser."""
    buf = _buffer(client)
    if buf is None or not hasattr(buf, "max_window_size"):
        return False
    buf.max_window_size = max(int(buf.max_window_size), int(at_least))
    return True


def gui_uuid(handle) -> str:
    """The id of a GUI element (what the page names in a ``GuiUpdateMessage``)."""
    return handle._impl.uuid


# ------------------------------------------------------------------ the camera, the poses
def camera_pose(camera) -> tuple[Any, Any] | None:
    """(position, look_at) of viser's state of a browser's camera (numpy arrays, updated in
    place by :func:`send_camera`), or None when viser's camera differs from 1.1's."""
    state = getattr(camera, "_state", None)
    if state is None or not hasattr(state, "client"):
        return None
    return state.position, state.look_at


def send_camera(camera, position: tuple | None = None, look_at: tuple | None = None) -> bool:
    """Queue the messages ``camera.position = position`` and ``camera.look_at = look_at`` send
    (each one given), keeping viser's camera state, without recomputing the orientation;
    False (nothing done) when viser's camera differs from 1.1's."""
    state = getattr(camera, "_state", None)
    if state is None or not hasattr(state, "client"):
        return False
    from viser import _messages

    conn = state.client._websock_connection
    if position is not None:
        state.position = np.array(position)
        conn.queue_message(_messages.SetCameraPositionMessage(position))
    if look_at is not None:
        state.look_at = np.array(look_at)
        conn.queue_message(_messages.SetCameraLookAtMessage(look_at))
    state.update_timestamp = time.time()
    return True


POSE_SETTER_PARAMETERS = ["current", "value", "length", "queue", "make_message"]


def replace_pose_setter(replacement: Callable) -> bool:
    """Put ``replacement`` in the place of viser's ``_scene_handles._set_pose_vector`` (every
    ``handle.position = …`` / ``.wxyz = …`` goes through it); False, and nothing changed,
    when viser's has another signature."""
    from viser import _scene_handles

    original = getattr(_scene_handles, "_set_pose_vector", None)
    if original is replacement:
        return True
    if original is None or list(inspect.signature(original).parameters) != POSE_SETTER_PARAMETERS:
        return False
    _scene_handles._set_pose_vector = replacement
    return True


def pose_setter() -> Callable | None:
    """The pose setter viser's handles use now (``_scene_handles._set_pose_vector``)."""
    from viser import _scene_handles

    return getattr(_scene_handles, "_set_pose_vector", None)


# ------------------------------------------------------------------ the websocket server
def on_handshake(server, connect: Callable, disconnect: Callable) -> None:
    """Run ``connect(conn)`` / ``disconnect(conn)`` (coroutines, on viser's event loop) for
    every websocket connection, before anything is sent to it / once it has closed:
    ``conn.client_id`` names it."""
    ws = server._websock_server
    ws.on_client_connect(connect)
    ws.on_client_disconnect(disconnect)


def handshake(server, client_id: int):
    """The live websocket connection of ``client_id`` (websockets' ``ServerConnection``: its
    ``request`` — path and headers — and ``close(code, reason)``), or None once it has gone."""
    return server._websock_server._live_connections.get(client_id)


def http_server(port: int):
    """viser's HTTP and websocket server on ``port`` (websockets' asyncio ``Server``, found
    among the process's objects); RuntimeError when it is not found."""
    import gc

    import viser
    from websockets.asyncio.server import Server

    found = [
        o
        for o in gc.get_objects()
        # the type itself: isinstance() asks a weakref.proxy for its referent's class, and a
        # dead proxy anywhere in the process raised ReferenceError (a CI run, after other tests)
        if issubclass(type(o), Server)
        and o.server is not None
        and any(sock.getsockname()[1] == port for sock in o.server.sockets)
    ]
    if len(found) != 1:
        raise RuntimeError(f"viser's HTTP server on port {port} not found (viser {viser.__version__})")
    return found[0]


def guard_http(port: int, refusal: Callable[[Any], str | None]) -> None:
    """Answer an HTTP request to viser's server on ``port`` (the page and its scripts, not the
    websocket) with 403 and ``refusal(request)`` when that gives a reason (None: served)."""
    from http import HTTPStatus

    server = http_server(port)
    original = server.process_request

    def process_request(conn, request):
        if request.headers.get("Upgrade", "").lower() != "websocket":  # the websocket has its own gate
            reason = refusal(request)
            if reason is not None:
                return conn.respond(HTTPStatus.FORBIDDEN, reason + "\n")
        return original(conn, request) if original is not None else None

    server.process_request = process_request


# ------------------------------------------------------------------ the page (viser's client)
#: the names of ``window.__viserMutable`` the page scripts use (the compat test looks for them
#: in viser's client)
PAGE_NAMES = ("__viserMutable", "sendMessage", "messageQueue", "drainMessageQueue", "getRenderRequestState")


def page_send(uuid: str) -> str:
    """Script defining ``send(obj)``: ``obj`` as JSON into the text box ``uuid`` (a
    ``GuiUpdateMessage``, what typing in it sends); returns early without viser's client."""
    return (
        "const m = window.__viserMutable; if (!m || !m.sendMessage) return;"
        "const send = (o) => m.sendMessage({type: 'GuiUpdateMessage', uuid: "
        + json.dumps(uuid)
        + ", updates: {value: JSON.stringify(o)}});"
    )


#: ``install(m)``, ``m`` the page's ``window.__viserMutable``: every batch of messages drained
#: as it arrives (a microtask after the task that queued it, before any frame), so React
#: commits its props before the next frame draws it with its poses (see the module
#: docstring); once per page; false when viser's client lacks what it needs
WHOLE_FRAMES = """(m) => {
  const has = (k) => m && k in m;
  if (!has('messageQueue') || !Array.isArray(m.messageQueue) || !has('drainMessageQueue')) return false;
  if (!has('getRenderRequestState')) return false;
  if (m.__nmkaneWholeFrames) return true;
  const q = m.messageQueue, push = q.push;
  let due = false;
  const drain = () => {
    due = false;
    const ready = typeof m.drainMessageQueue === 'function' && m.getRenderRequestState === 'ready';
    if (q.length > 0 && ready) m.drainMessageQueue();
  };
  q.push = function () {
    const n = push.apply(this, arguments);
    if (!due) { due = true; queueMicrotask(drain); }
    return n;
  };
  m.__nmkaneWholeFrames = true;
  window.__nmkaneWholeFrames = true;
  return true;
}"""


def whole_frames_source() -> str:
    """:data:`WHOLE_FRAMES` for the live page (:func:`run_javascript`: run by viser's client,
    which is mounted by then)."""
    return "(" + WHOLE_FRAMES + ")(window.__viserMutable);"


def whole_frames_script() -> str:
    """A ``<script>`` for a page of its own (the export): :data:`WHOLE_FRAMES` installed once
    viser's client has mounted (looked for every 50 ms, for at most a minute)."""
    return (
        "<script>(function () { const install = " + WHOLE_FRAMES + "; let tries = 0;"
        " const go = () => { if (!install(window.__viserMutable) && ++tries < 1200) setTimeout(go, 50); };"
        " go(); })();</script>"
    )
