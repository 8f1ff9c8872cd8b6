"""viser through one door (issue 43): every function of web/viser_compat.py against the
installed viser, through a real connection (a bare websocket client speaking viser's protocol
stands in for the browser), so that an upgrade renaming an internal fails here, the message
naming the function; the pin in pyproject.toml is the one the module was checked against; and
no other module of web/ touches viser's private API."""

import ast
import contextlib
import functools
import socket
import sys
import threading
import tomllib
import warnings
from pathlib import Path

import msgspec
import numpy as np
import pytest
import viser
import zstandard
from packaging.requirements import Requirement
from packaging.specifiers import SpecifierSet
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from tests._helpers import SCRIPTS, until
from web import viser_compat as compat

if str(SCRIPTS) not in sys.path:  # the load scripts' headless viser client
    sys.path.insert(0, str(SCRIPTS))
import viser_client

ROOT = Path(__file__).resolve().parents[2]
VISER = Path(viser.__file__).resolve().parent
#: the camera the raw client reports (the load scripts' client's, looking a little above the origin)
CAMERA = {**viser_client.CAMERA, "look_at": (0.0, 0.0, 0.5)}


#: a wait on what a connection delivers (20 s at the most, polled every 20 ms)
soon = functools.partial(until, timeout=20.0, every=0.02)


def must(ok: bool, function: str, what: str) -> None:
    """An assertion naming the compat function that no longer works with this viser."""
    assert ok, f"web.viser_compat.{function} with viser {viser.__version__}: {what}"


class RawClient:
    """A websocket client of a viser server, as the page is: it reports its camera, then keeps
    every window the server sends (decoded: the messages of one websocket message)."""

    def __init__(self, port: int, host: str | None = None):
        self.windows: list[list[dict]] = []
        self.ws = connect(
            f"ws://127.0.0.1:{port}",
            subprotocols=[f"viser-v{viser.__version__}"],
            additional_headers={"Host": host} if host else None,
            max_size=None,
        )
        self._dctx = zstandard.ZstdDecompressor()
        threading.Thread(target=self._read, daemon=True).start()
        self.ws.send(msgspec.msgpack.encode(CAMERA))

    def _read(self) -> None:
        with contextlib.suppress(ConnectionClosed, OSError):
            while True:
                self.windows.append(viser_client.decode_window(self.ws.recv(), self._dctx))

    def messages(self, kind: str) -> list[dict]:
        return [m for w in list(self.windows) for m in w if m.get("type") == kind]

    def send(self, message: dict) -> None:
        self.ws.send(msgspec.msgpack.encode(message))

    def close(self) -> None:
        self.ws.close()


@pytest.fixture()
def connected(server):
    """(the raw client, viser's ClientHandle of it)."""
    raw = RawClient(server.get_port())
    assert soon(lambda: len(server.get_clients()) == 1), "no client connected"
    yield raw, next(iter(server.get_clients().values()))
    raw.close()


# ------------------------------------------------------------------ the pin
def test_the_pin_in_pyproject_is_the_one_checked_and_installed():
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    pins = {name: str(Requirement(r).specifier) for name, reqs in extras.items() for r in reqs if r.startswith("viser")}
    assert set(pins) == {"web", "notebook"}, pins
    assert all(SpecifierSet(p) == SpecifierSet(compat.PINNED) for p in pins.values()), (pins, compat.PINNED)
    installed = viser.__version__
    assert installed in SpecifierSet(compat.PINNED), f"viser {installed} installed, {compat.PINNED} pinned"
    assert compat.CHECKED in SpecifierSet(compat.PINNED)


# ------------------------------------------------------------------ one browser's connection
def test_connection_queue_and_run_javascript(connected):
    raw, client = connected
    must(compat.connection(client) is not None, "connection", "no websocket connection on the ClientHandle")
    must(callable(compat.queue(client)), "queue", "no message queue")
    must(compat.run_javascript(client, "window.__nmkaneProbe = 1;"), "run_javascript", "refused a connected client")
    sent = lambda: [m["source"] for m in raw.messages("RunJavascriptMessage")]  # noqa: E731
    must(soon(lambda: "window.__nmkaneProbe = 1;" in sent()), "run_javascript", "the script did not arrive")
    assert compat.connection(None) is None and compat.queue(None) is None
    assert compat.run_javascript(None, "1;") is False  # a test's shared server: no page


def test_gui_uuid_is_what_the_page_names_in_an_update(server, connected):
    raw, _ = connected
    box = server.gui.add_text("box", "")
    raw.send({"type": "GuiUpdateMessage", "uuid": compat.gui_uuid(box), "updates": {"value": "typed"}})
    must(soon(lambda: box.value == "typed"), "gui_uuid", "an update naming it did not reach the box")


def test_whole_windows_sends_a_big_batch_as_one_websocket_message(connected):
    raw, client = connected
    n = 3 * 128  # viser's default window: 128 messages (a frame node takes more than one)
    must(compat.whole_windows(client, at_least=8 * n), "whole_windows", "no window size on the message buffer")
    with client.atomic():
        for i in range(n):
            client.scene.add_frame(f"/batch/f{i}", show_axes=False)

    def windows() -> list[int]:
        return [sum(m["type"] == "FrameMessage" and m["name"].startswith("/batch/") for m in w) for w in raw.windows[:]]

    must(soon(lambda: sum(windows()) >= n), "whole_windows", "the batch did not arrive")
    must(max(windows()) == n, "whole_windows", f"a batch of {n} arrived split: {[k for k in windows() if k]}")
    assert compat.whole_windows(None) is False


def test_backlog_and_writes_racing_a_leave(server, connected):
    raw, client = connected
    left = compat.backlog(client)
    must(isinstance(left, int) and left >= 0, "backlog", f"{left!r} for a connected client")
    raw.close()
    must(soon(lambda: not server.get_clients()), "backlog", "the client did not leave")
    must(compat.backlog(client) == -1, "backlog", "a closed connection not reported as −1")
    scope = compat.dead_writes_allowed(client)
    must(not isinstance(scope, contextlib.nullcontext), "dead_writes_allowed", "no scope on the message buffer")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with compat.dead_writes_allowed(client):
            client.scene.add_frame("/late/inside", show_axes=False)
        quiet = [str(w.message) for w in caught if "closed connection" in str(w.message)]
        client.scene.add_frame("/late/outside", show_axes=False)
        loud = [str(w.message) for w in caught if "closed connection" in str(w.message)]
    must(not quiet, "dead_writes_allowed", f"a write inside the scope warned: {quiet}")
    must(len(loud) == 1, "dead_writes_allowed", "no warning outside the scope: the check above proves nothing")
    assert compat.backlog(None) == 0 and isinstance(compat.dead_writes_allowed(None), contextlib.nullcontext)


# ------------------------------------------------------------------ the camera and the poses
def test_camera_pose_and_send_camera(connected):
    raw, client = connected
    pose = compat.camera_pose(client.camera)
    must(pose is not None, "camera_pose", "no camera state")
    assert pose is not None
    must(np.allclose(pose[0], CAMERA["position"]), "camera_pose", f"position {pose[0]} not the reported one")
    must(np.allclose(pose[1], CAMERA["look_at"]), "camera_pose", f"look_at {pose[1]} not the reported one")
    must(compat.send_camera(client.camera, (1.0, 2.0, 3.0), (0.0, 0.0, 1.0)), "send_camera", "refused")
    must(
        soon(lambda: raw.messages("SetCameraPositionMessage") and raw.messages("SetCameraLookAtMessage")),
        "send_camera",
        "the camera's messages did not arrive",
    )
    assert tuple(raw.messages("SetCameraPositionMessage")[-1]["position"]) == (1.0, 2.0, 3.0)
    assert tuple(raw.messages("SetCameraLookAtMessage")[-1]["look_at"]) == (0.0, 0.0, 1.0)
    now = compat.camera_pose(client.camera)
    assert now is not None
    must(np.allclose(now[0], (1, 2, 3)) and np.allclose(now[1], (0, 0, 1)), "send_camera", "state not kept")
    assert compat.camera_pose(object()) is None and compat.send_camera(object(), (0, 0, 0)) is False


def test_replace_pose_setter(server):
    before = compat.pose_setter()
    must(before is not None, "pose_setter", "viser's pose setter not found")
    calls = []

    def counting(current, value, length, queue, make_message):
        calls.append(value)
        before(current, value, length, queue, make_message)

    try:
        must(compat.replace_pose_setter(counting), "replace_pose_setter", "viser's setter has another signature")
        must(compat.pose_setter() is counting, "replace_pose_setter", "not in place")
        node = server.scene.add_frame("/posed", show_axes=False)
        made = len(calls)
        node.position = (1.0, 2.0, 3.0)
        must(calls[made:] == [(1.0, 2.0, 3.0)], "replace_pose_setter", f"handle.position not through it: {calls}")
    finally:
        assert compat.replace_pose_setter(before)  # as it was (web.fastpath's, if installed)
    assert compat.pose_setter() is before


# ------------------------------------------------------------------ the websocket and HTTP server
def test_on_handshake_and_handshake(server):
    seen, gone = [], []

    async def connect_(conn):
        ws = compat.handshake(server, conn.client_id)
        seen.append(None if ws is None else ws.request.headers.get("Host"))

    async def disconnect(conn):
        gone.append(conn.client_id)

    compat.on_handshake(server, connect_, disconnect)
    raw = RawClient(server.get_port())
    host = f"127.0.0.1:{server.get_port()}"
    must(soon(lambda: bool(seen)), "on_handshake", "the connect callback did not run")
    must(seen == [host], "handshake", f"the connection's Host read {seen}, not {host!r}")
    raw.close()
    must(soon(lambda: bool(gone)), "on_handshake", "the disconnect callback did not run")


def _get(port: int, host: str) -> tuple[int, bytes]:
    with socket.create_connection(("127.0.0.1", port), timeout=20) as sock:
        sock.sendall(f"GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
        data = b""
        while chunk := sock.recv(65536):
            data += chunk
    return int(data.split(b" ", 2)[1]), data


def test_http_server_and_guard_http(server):
    port = server.get_port()
    found = compat.http_server(port)
    must(any(s.getsockname()[1] == port for s in found.server.sockets), "http_server", "another server found")
    compat.guard_http(port, lambda request: "nope" if request.headers.get("Host") == "evil.example" else None)
    status, body = _get(port, "evil.example")
    must(status == 403 and b"nope" in body, "guard_http", f"a refused host got {status}")
    status, body = _get(port, f"127.0.0.1:{port}")
    must(status == 200 and b"<html" in body.lower(), "guard_http", f"an allowed host got {status}")
    with socket.socket() as free:
        free.bind(("127.0.0.1", 0))
        with pytest.raises(RuntimeError, match="not found"):
            compat.http_server(free.getsockname()[1])


# ------------------------------------------------------------------ the page side
def test_the_page_side_names_are_in_visers_client():
    """The names of ``window.__viserMutable`` the page scripts use (the whole-frames script, the
    answers through a text box), in the client sources viser ships; the browser tests
    (test_frames_whole_browser.py) check them at work."""
    src = VISER / "client" / "src"
    assert src.is_dir(), f"viser {viser.__version__} ships no client sources: run test_frames_whole_browser.py"
    text = "\n".join(p.read_text(errors="ignore") for p in src.rglob("*.ts*"))
    for name in compat.PAGE_NAMES:
        must(name in text, "WHOLE_FRAMES / page_send", f"{name!r} not in viser's client")
    runs = "new Function(message.source)" in text or "eval(message.source)" in text
    must(runs, "run_javascript", "the client no longer runs a RunJavascriptMessage's source")
    must("queue.push(" in text, "WHOLE_FRAMES", "the client no longer pushes arriving messages on messageQueue")
    assert "UUID" not in compat.page_send("u-1") and '"u-1"' in compat.page_send("u-1")
    assert compat.WHOLE_FRAMES in compat.whole_frames_source() and compat.WHOLE_FRAMES in compat.whole_frames_script()


# ------------------------------------------------------------------ one door
def _viser_private_names() -> set[str]:
    """Every underscore name of viser's package: its private modules, functions, classes and
    attributes (dunders left out)."""
    names: set[str] = set()
    for path in VISER.rglob("*.py"):
        if path.stem.startswith("_") and not path.stem.startswith("__"):
            names.add(path.stem)
        for node in ast.walk(ast.parse(path.read_text(errors="ignore"))):
            name = getattr(node, "name", None) if not isinstance(node, ast.Attribute) else node.attr
            if isinstance(name, str) and name.startswith("_") and not name.startswith("__") and len(name) > 2:
                names.add(name)
    return names


def _docstrings(tree) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        first = body[0] if isinstance(body, list) and body else None
        if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) and isinstance(first.value.value, str):
            out.add(id(first.value))
    return out


ATTRIBUTE_CALLS = {"getattr", "setattr", "hasattr", "delattr"}


def _is_script(node) -> bool:
    """A string reaching into viser's client (a page script)."""
    return isinstance(node, ast.Constant) and isinstance(node.value, str) and "__viserMutable" in node.value


def private_uses(source: str, private: set[str]) -> list[str]:
    """Where ``source`` touches viser's private API: imports of its private modules or of the
    websockets server under it, ``x._name`` (``x`` not self) or ``getattr(x, "_name")`` naming
    a private name of viser, and page scripts reaching into viser's client (``__viserMutable``)."""
    tree = ast.parse(source)
    docs = _docstrings(tree)
    found = []
    for node in ast.walk(tree):
        where = f"line {getattr(node, 'lineno', '?')}"
        if isinstance(node, ast.ImportFrom) and node.module:
            parts = node.module.split(".")
            if parts[0] == "websockets" or (
                parts[0] == "viser" and any(p.startswith("_") or p == "infra" for p in parts[1:])
            ):
                found.append(f"{where}: from {node.module} import …")
            elif node.module == "viser":
                found += [f"{where}: from viser import {a.name}" for a in node.names if a.name.startswith("_")]
                found += [f"{where}: from viser import infra" for a in node.names if a.name == "infra"]
        elif isinstance(node, ast.Import):
            for a in node.names:
                parts = a.name.split(".")
                if parts[0] == "websockets" or (parts[0] == "viser" and any(p.startswith("_") for p in parts[1:])):
                    found.append(f"{where}: import {a.name}")
        elif isinstance(node, ast.Attribute) and node.attr in private:
            if not (isinstance(node.value, ast.Name) and node.value.id in ("self", "cls")):
                found.append(f"{where}: {ast.unparse(node)}")
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ATTRIBUTE_CALLS:
            named = node.args[1] if len(node.args) > 1 else None
            if isinstance(named, ast.Constant) and named.value in private:
                found.append(f"{where}: {ast.unparse(node)}")
        elif _is_script(node) and id(node) not in docs:
            found.append(f"{where}: {node.value[:60]!r}")
    return found


def test_the_scan_finds_each_kind_of_private_use():
    """The scan below, on a sample of what web/ did before it went through one door."""
    private = _viser_private_names()
    assert {"_websock_connection", "_websock_server", "_impl", "_state", "_messages", "_scene_handles"} <= private
    sample = """
import viser
from viser import _messages, uplot
from viser._scene_handles import SceneNodeHandle
from websockets.asyncio.server import Server
conn = client._websock_connection
uuid = box._impl.uuid
ws = server._websock_server._live_connections
q = getattr(client, "_websock_connection", None)
JS = "window.__viserMutable.sendMessage(x)"
ok = self._lock, app._lock, field._refuse, os._exit
"""
    found = private_uses(sample, private)
    lines = sorted(int(f.split(":")[0].split()[1]) for f in found)
    assert lines == [3, 4, 5, 6, 7, 8, 8, 9, 10], "\n".join(found)  # line 8: two names; line 11 is ours


def test_no_module_of_web_but_viser_compat_touches_visers_private_api():
    private = _viser_private_names()
    found = [
        f"web/{path.name}: {use}"
        for path in sorted((ROOT / "web").glob("*.py"))
        if path.name != "viser_compat.py"
        for use in private_uses(path.read_text(), private)
    ]
    assert not found, "viser's private API outside web/viser_compat.py:\n" + "\n".join(found)
