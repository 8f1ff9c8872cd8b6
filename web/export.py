"""A run as one self-contained HTML file that plays offline: ``nmkane export``, the page's
*Export* button and ``run.show()`` in Jupyter all call :func:`export_html`.

The 3D animation is the page's own scene — the same :class:`~web.generic.GenericView` (the
system's declared visuals, its force arrows, a ghost per compare run) built on a private,
short-lived viser server bound to a free loopback port (viser records only what is sent through
a server's scene) — recorded with viser's scene serializer: the nodes once, then one pose
per frame with the time between frames.  viser's standalone client (one HTML file with its
scripts compressed inside, no CDN) plays the recording with its playback bar: play, pause,
scrub and speed.  The plots and summary (:mod:`web.export_panel`) are put beside it as
inline SVG, with a cursor that follows the playback bar.

**Frames.**  The recording plays the run at the system's showcase speed (1× unless it
declares another, e.g. a 0.03 s benchmark slowed down), at :data:`FPS` frames per second of
playback, at most :data:`MAX_FRAMES` frames (a longer run gets fewer frames per second: the
file stays near 1–2 MB); each frame shows the output row at or just before its time.
The camera frames the whole motion (every path travelled: the file's camera does not follow), left
of the plots.
"""

from __future__ import annotations

import contextlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from nmkane_core.cli.common import check_writable
from nmkane_core.errors import InputError, NmkaneError

from .runs import Trajectory

FPS = 30.0  # frames per second of playback
MAX_FRAMES = 1200  # frames of one file at most (40 s at 30 fps; a 10 s run: 301 frames, about 1.1 MB)
HTML, GIF = ".html", ".gif"  # the page, or a film of it (:mod:`web.export_gif`)


@dataclass(frozen=True)
class Frames:
    """When the recording shows what: the simulated time of each frame, the playback time
    between two frames, and the playback speed (simulated seconds per second)."""

    times: np.ndarray
    step_s: float
    speed: float

    @property
    def duration_s(self) -> float:
        """How long the recording plays at 1× on its playback bar."""
        return self.step_s * (len(self.times) - 1)


def frames(t_end: float, speed: float = 1.0, fps: float = FPS, max_frames: int = MAX_FRAMES) -> Frames:
    """Frames of a run ending at ``t_end`` played at ``speed``: ``fps`` per second of playback,
    at most ``max_frames`` (then fewer per second), at least the first and the last row."""
    speed = speed if speed > 0 and np.isfinite(speed) else 1.0
    t_end = max(float(t_end), 0.0)
    playback = t_end / speed
    n = int(min(max(round(playback * fps) + 1, 2), max_frames))
    times = np.linspace(0.0, t_end, n)
    return Frames(times, playback / (n - 1), speed)


def check_out(path: str | Path, suffixes: tuple[str, ...] = (HTML, GIF)) -> Path:
    """An export's file name: it must end in one of ``suffixes`` (``.html``, or ``.gif``),
    in an existing folder this user may write (InputError naming ``out`` otherwise: the
    command line's own check, :func:`nmkane_core.cli.common.check_writable`)."""
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        film = " (or .gif: a film of the page)" if GIF in suffixes[1:] else ""
        raise InputError("out", str(path), f"a file name ending in {suffixes[0]}{film}", "unknown format")
    check_writable("out", str(path))
    return p


def trajectory(runs) -> Trajectory:
    """A :class:`~web.runs.Trajectory` of a core Run, or of runs by label (the shown one first,
    then compare runs, all of one system)."""
    if not isinstance(runs, dict):
        runs = {runs.settings.get("model") or runs.settings.get("formulation") or runs.system: runs}
    if not runs:
        raise InputError("runs", runs, "at least one run")
    main = next(iter(runs.values()))
    if any(r.system != main.system for r in runs.values()):
        raise InputError("runs", sorted({r.system for r in runs.values()}), "runs of one system")
    request = {"settings": dict(main.settings), "options": {}}
    return Trajectory(main.system, request, dict(runs), dict(main.settings["params"]), {}, 0.0)


@contextlib.contextmanager
def _private_server():
    """A viser server of our own on a free loopback port, silent (its banner and its
    goodbye go to a buffer), stopped afterwards."""
    import viser

    from . import fastpath

    fastpath.install()  # plain-float poses, as the live page sends them (and msgpack encodes)
    with _quiet():
        server = viser.ViserServer(host="127.0.0.1", port=0, label="nmkane export", verbose=False)
    try:
        yield server
    finally:
        with _quiet():
            server.stop()


@contextlib.contextmanager
def _quiet():
    """viser's banner and goodbye into a buffer: they go to stdout, or in Jupyter (rich's console
    sees the notebook) to the cell's output as rich displays, beside the exported scene."""
    import rich

    console = rich.get_console()
    saved = dict(console.__dict__)
    rich.reconfigure(file=io.StringIO(), force_jupyter=False, force_terminal=False)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            yield
    finally:
        console.__dict__.clear()
        console.__dict__.update(saved)


def record(traj: Trajectory, shots: Frames | None = None, viewport=None) -> tuple[str, object, Frames]:
    """The recorded animation as viser's standalone HTML; returns (html, the view, the frames)."""
    from .camera import Viewport
    from .generic import GenericView
    from .labels import LabelLayout, seen_from

    with _private_server() as server:
        recording = server.get_scene_serializer()
        view = GenericView(server.scene, traj.kind)
        view.install(traj)
        view.root.visible = True
        shots = shots or frames(traj.t_end, view.speed)
        vp = viewport or Viewport()
        plan = view.camera_plan(vp)
        seen = None  # the file's camera, for keeping the labels apart (web.labels)
        if plan is not None:
            look_at, position = plan.whole
            server.initial_camera.position = tuple(float(v) for v in position)
            server.initial_camera.look_at = tuple(float(v) for v in look_at)
            seen = seen_from(look_at, position, vp)
        labels = LabelLayout()
        for i, t in enumerate(shots.times):
            if i:
                recording.insert_sleep(shots.step_s)
            view.pose(traj, float(t))
            labels.apply(view.label_points(), seen)
        return recording.as_html(), view, shots


def export_page(runs, title: str | None = None) -> tuple[str, Frames]:
    """The self-contained HTML file of a run (a core Run, or runs by label: the shown one
    first, then compare runs drawn as ghosts, or a :class:`~web.runs.Trajectory`), as text,
    and the frames it holds."""
    from .export_panel import inject

    traj = runs if isinstance(runs, Trajectory) else trajectory(runs)
    page, view, shots = record(traj)
    return inject(page, view, traj, shots, title), shots


def export_html(runs, title: str | None = None) -> str:
    """:func:`export_page`'s text alone."""
    return export_page(runs, title)[0]


def write(runs, path: str | Path) -> Path:
    """Export to ``path`` (``.html``; a film of the page: :func:`web.export_gif.write_gif`);
    the file appears whole or not at all."""
    out = check_out(path, (HTML,))
    partial = out.with_name(out.name + ".part")
    partial.write_text(export_html(runs), encoding="utf-8")
    partial.replace(out)
    return out


def show(runs, height: int = 640):
    """The export inline in Jupyter: an ``IPython.display.HTML`` holding an iframe whose
    ``srcdoc`` is the exported file (plays offline, fetches nothing).  The last line of a
    cell displays it; elsewhere ``IPython.display.display(run.show())``."""
    import html

    try:
        from IPython.display import HTML
    except ImportError:  # the web extra without Jupyter
        raise NmkaneError("show() displays in Jupyter: pip install 'nmkane[notebook]'") from None
    doc = html.escape(export_html(runs), quote=True)
    return HTML(  # in a div: IPython warns about a bare iframe ("consider IFrame", which has no srcdoc)
        f'<div><iframe srcdoc="{doc}" width="100%" height="{int(height)}" '
        'style="border:1px solid #ddd" title="nmkane run"></iframe></div>'
    )
