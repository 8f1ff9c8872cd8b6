"""A headless viser client: speaks viser 1.1's websocket protocol, counts the frames it receives.

Used by ``scripts/classroom.py`` (many of them in one asyncio loop) and by its test.

The protocol (``viser/infra/_infra.py``, ``client/src/WebsocketClientWorker.ts``): the page
opens a websocket with the subprotocol ``viser-v<version>``; the server sends binary
messages, each a window of messages::

    [8 bytes] size of the msgpack payload, little-endian
    [8 bytes] size of its zstd-compressed form
    [N bytes] zstd-compressed msgpack {"messages": [{"type": ..., ...}, ...], "timestampSec", ...}
    [padding to 8 bytes, then raw binary buffers]

and the client sends msgpack-encoded messages (a dict with ``"type"``).  The client here
reports its camera once (``ViewerCameraMessage``, as the browser does on load) and counts a
*frame* for every window that moves a scene node (``SetPositionMessage`` or
``SetOrientationMessage``).
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import msgspec
import zstandard

POSE_TYPES = frozenset({"SetPositionMessage", "SetOrientationMessage"})
CAMERA = {
    "type": "ViewerCameraMessage",
    "wxyz": (1.0, 0.0, 0.0, 0.0),
    "position": (3.0, -3.0, 2.0),
    "fov": 1.309,
    "near": 0.01,
    "far": 1000.0,
    "image_height": 900,
    "image_width": 1400,
    "look_at": (0.0, 0.0, 0.0),
    "up_direction": (0.0, 0.0, 1.0),
}


def decode_window(data: bytes, dctx: zstandard.ZstdDecompressor) -> list[dict]:
    """The messages of one server window (``data``: one binary websocket message)."""
    size = int.from_bytes(data[:8], "little")
    csize = int.from_bytes(data[8:16], "little")
    inner = dctx.decompress(data[16 : 16 + csize], max_output_size=size)
    return msgspec.msgpack.decode(inner)["messages"]


@dataclass
class ClientStats:
    """What one client saw: ``frames`` (times of windows moving a node), message counts by
    type, bytes received, and how it ended (``error``: None, or why it failed)."""

    index: int
    frames: list[float] = field(default_factory=list)
    windows: int = 0
    bytes: int = 0
    types: dict[str, int] = field(default_factory=dict)
    connected_at: float | None = None
    error: str | None = None
    close: str | None = None

    def fps(self, t0: float, t1: float) -> float:
        """Frames per second received between monotonic times t0 and t1."""
        n = sum(1 for t in self.frames if t0 <= t < t1)
        return n / (t1 - t0) if t1 > t0 else 0.0


async def run_client(
    url: str,
    version: str,
    stop_at: float,
    stats: ClientStats,
    host: str | None = None,
    origin: str | None = None,
    enough: Callable[[ClientStats], bool] | None = None,
) -> None:
    """Connect to ``url`` (``ws://host:port/``) as viser ``version``'s client and receive until
    the monotonic time ``stop_at``, or until ``enough(stats)`` holds; fills ``stats``.
    ``host``/``origin``: headers to send (None: the URL's host, no Origin)."""
    import websockets.asyncio.client as wsc
    from websockets.exceptions import ConnectionClosed

    dctx = zstandard.ZstdDecompressor()
    headers = {"Origin": origin} if origin else {}
    try:
        async with wsc.connect(
            url,
            subprotocols=[f"viser-v{version}"],
            max_size=None,
            compression=None,
            additional_headers=headers,
            open_timeout=30,
        ) as ws:
            stats.connected_at = time.monotonic()
            await ws.send(msgspec.msgpack.encode(CAMERA))
            while True:
                left = stop_at - time.monotonic()
                if left <= 0:
                    break
                try:
                    data = await asyncio.wait_for(ws.recv(), timeout=left)
                except TimeoutError:
                    break
                now = time.monotonic()
                if not isinstance(data, bytes):
                    continue
                stats.windows += 1
                stats.bytes += len(data)
                moved = False
                for m in decode_window(data, dctx):
                    kind = m.get("type", "?")
                    stats.types[kind] = stats.types.get(kind, 0) + 1
                    moved = moved or kind in POSE_TYPES
                if moved:
                    stats.frames.append(now)
                if enough is not None and enough(stats):
                    break
    except ConnectionClosed as e:
        stats.close = f"{e.rcvd.code if e.rcvd else '?'} {e.rcvd.reason if e.rcvd else ''}".strip()
        stats.error = f"closed by the server: {stats.close}"
    except Exception as e:  # reported per client; the script decides
        stats.error = f"{type(e).__name__}: {e}"


async def run_clients(
    url: str,
    version: str,
    n: int,
    seconds: float,
    stagger_s: float = 0.1,
    enough: Callable[[ClientStats], bool] | None = None,
) -> list[ClientStats]:
    """``n`` clients connecting ``stagger_s`` apart, each receiving until ``seconds`` after
    the first connected, or until ``enough(its stats)`` holds."""
    stop_at = time.monotonic() + seconds
    stats = [ClientStats(i) for i in range(n)]
    tasks = []
    for s in stats:
        tasks.append(asyncio.create_task(run_client(url, version, stop_at, s, enough=enough)))
        await asyncio.sleep(stagger_s)
    await asyncio.gather(*tasks)
    return stats
