"""One browser's page: its controls, scene, camera and trajectory, wired together.

Every connected browser gets its own :class:`MechanismApp`, so students exploring at once
do not change each other's view.  Every system is shown by the same
:class:`~web.generic.GenericView` (one scene, one simulation folder and one set of plots
per system, built when it is first chosen, the chosen one visible).

:class:`MechanismApp` is a small coordinator: it builds the panel in order and wires it, and
its three concerns live apart —

* :mod:`web.playback` — the shown time, play/pause, speed, the scrubber, the camera's
  looking, and the animation frames (each frame whole: one batch);
* :mod:`web.scenes` — the *Scene* dropdown, one view and simulation folder per system,
  the shown system's controls, defaults and links;
* :mod:`web.session_runs` — a control change read into a request, run by
  :class:`web.runs.Runner`, installed; the status line.

The other parts live in :mod:`web.controls` (handles and their guard), :mod:`web.panel`
(plots, summary, status, matrices), :mod:`web.camera`, :mod:`web.page` (the page's own
scripts) and :mod:`web.lighting`.  The animation thread of :mod:`web.server` calls
:meth:`MechanismApp.tick`.  The session's names are those of the three parts, so
``app.t_now``, ``app.control("gamma")``, ``app.install(traj)`` read as before.
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import viser

from nmkane_core.run.simulate import simulate as core_simulate

from . import viser_compat as compat
from .camera import CameraRig
from .controls import ControlPanel
from .export_button import ExportButton
from .generic import GenericView, scene_choices
from .keys import add_keys
from .lighting import Lighting
from .link import LinkPanel
from .numbers import HIDE_SLIDER_BOXES
from .page import PageBridge, is_software
from .panel import MatricesPanel, PlotPanel
from .playback import Playback
from .runs import Trajectory
from .scenes import Scenes
from .session_runs import SessionRuns
from .study import StudyPanel

SHADOWS_HINT = (
    "The bodies' shadows on the ground. Off by itself where the browser draws without a graphics "
    "card (software WebGL), where they more than double the cost of a frame."
)


def racing_a_leave(client):
    """The scope of writes that may race the browser's leaving: a page being built, a run
    being installed, an animation frame (:func:`web.viser_compat.dead_writes_allowed`)."""
    return compat.dead_writes_allowed(client)


def _part(name: str, attr: str, doc: str = ""):
    """A session attribute kept by one of its parts (read and written there)."""
    return property(
        lambda self: getattr(getattr(self, name), attr),
        lambda self, value: setattr(getattr(self, name), attr, value),
        doc=doc or f"``{name}.{attr}``",
    )


class MechanismApp:
    """The controls, scene, camera and trajectory of one browser (or of a test).

    ``target`` is a :class:`viser.ClientHandle` (the per-browser case) or a
    :class:`viser.ViserServer` (tests, a single shared view).  With ``sync=True`` every
    control change simulates in the calling thread (deterministic tests); otherwise a
    :class:`~web.worker.LatestWorker` does it in the background.  ``connected()`` says
    whether the browser is still there (nothing is sent to one that left).

    ``scene`` names the system shown first (default: the first registered).  The shown
    system's controls are found by their field with :meth:`control` (``app.control("gamma")``,
    ``app.control("params.m")``)."""

    def __init__(
        self,
        target,
        *,
        simulate=core_simulate,
        sync: bool = False,
        connected: Callable[[], bool] | None = None,
        scene: str | None = None,
    ):
        self.target = target
        self.client = target if isinstance(target, viser.ClientHandle) else None
        self.gui, self.scene = target.gui, target.scene
        self._connected = connected
        self.lock = threading.RLock()
        self.closed = False
        self.renderer = ""  # the page's WebGL renderer, once it has said (web.page)
        compat.whole_windows(self.client)  # a run's batch reaches the page as one message
        self.lighting = Lighting(self.client)  # plain lights until the page says a graphics card draws it
        choices = scene_choices()  # dropdown title -> system name
        first = next((t for t, n in choices.items() if n == scene), None) if scene else None
        first = first or next(iter(choices))
        self.camera = CameraRig(self.client, self.alive)
        self.runs = SessionRuns(self, simulate, sync=sync)
        self.playback = Playback(self)
        self.scenes = Scenes(self, choices)
        self._build_gui(first)
        if self.client is not None:
            self.client.camera.on_update(lambda cam: self.camera.on_report(cam))
        self._on_scene()
        self.link.start()  # the page says which link it was opened with; then its address follows the page
        self.bridge.whole_frames()  # the page shows each frame whole (web.viser_compat.WHOLE_FRAMES)
        self.bridge.help_plots()
        self.bridge.ask_renderer()  # software WebGL: shadows off (self._on_page)

    # ---------------------------------------------------------------- GUI
    def _build_gui(self, first: str) -> None:
        gui = self.gui
        gui.add_html(HIDE_SLIDER_BOXES)  # viser's own slider boxes misread typing: ours are above them
        self.controls = ControlPanel(gui, self.runs.show_refusals, self.lock)
        gui.add_markdown("Nonminimal Kane's equations — Bajodah, Hodges & Chen (2005)")
        self.scenes.add_dropdown(first)
        self.runs.add_status(gui)
        self.bridge = PageBridge(gui, self.client, self._on_page)
        self.link = LinkPanel(gui, self)

        with self._form("Playback"):
            self.playback.add_controls(gui, self.controls)
            self.shadows = gui.add_checkbox("Shadows", initial_value=True, hint=SHADOWS_HINT)
            self.view_reset = gui.add_button("Reset view")
            self.fit_view = gui.add_button("Fit view")
            self.export = ExportButton(gui, self)  # the shown run as one offline HTML file
            self.keys = add_keys(gui, self)

        self.scenes.add_first(first)

        with gui.add_folder("Plots and summary") as self.plots_folder:
            self.plots = PlotPanel(gui, self.views)
            self.summary = self.plots.summary
            self.plot_handles = self.plots.handles

        with gui.add_folder("Derived matrices", expand_by_default=False):
            self.matrices = MatricesPanel(gui, self.lock, self.alive, lambda: racing_a_leave(self.client))

        # wiring: every simulation input re-simulates (web.scenes); playback controls do not
        self.scenes.wire()
        self.playback.wire(self.view_reset, self.fit_view)
        self.controls.on_change(self.shadows, self._light)
        with self._form("Γ study", expand_by_default=False):  # web/study.py; follows the scene itself
            self.study = StudyPanel(gui, self)

    def _form(self, label: str, **kw) -> viser.GuiFolderHandle:
        """A folder whose boxes apply what is typed on Enter (viser's form)."""
        return self.controls.form(label, **kw)

    # ---------------------------------------------------------------- the parts' names
    # playback (web.playback)
    playing = _part("playback", "playing")
    t_now = _part("playback", "t_now")
    _shown_t = _part("playback", "shown_t")
    play = property(lambda self: self.playback.play)
    speed = property(lambda self: self.playback.speed)
    time = property(lambda self: self.playback.time)
    follow = property(lambda self: self.playback.follow)

    def set_playing(self, playing: bool) -> None:
        self.playback.set_playing(playing)

    def fit(self) -> None:
        self.playback.fit()

    def reset_view(self) -> None:
        self.playback.reset_view()

    def _look(self, follow: bool | None) -> None:
        self.playback.look(follow)

    def seek(self, t: float) -> None:
        """Show time t (the scrubber, or a test)."""
        self.playback.seek(t)

    def _on_time(self) -> None:
        self.playback.on_time()

    def show_time(self, t_now: float) -> None:
        self.playback.show_time(t_now)

    def _refresh(self, force: bool = False) -> None:
        self.playback.refresh(force)

    def tick(self, dt_wall: float, refresh: bool) -> None:
        """One animation frame (called by the animation thread)."""
        self.playback.tick(dt_wall, refresh)

    def _atomic(self):
        return self.playback.frame()

    # scene switching (web.scenes)
    choices = property(lambda self: self.scenes.choices)
    views = property(lambda self: self.scenes.views)
    system_view = _part("scenes", "system_view")
    scene_choice = property(lambda self: self.scenes.scene_choice)
    sim_controls = property(lambda self: self.scenes.sim_controls)
    folders = property(lambda self: self.scenes.folders)
    legends = property(lambda self: self.scenes.legends)
    resets = property(lambda self: self.scenes.resets)

    @property
    def kind(self) -> str:
        return self.scenes.kind

    def current_kind(self) -> str:
        return self.scenes.kind

    def view_of(self, kind: str) -> GenericView:
        return self.scenes.views[kind]

    def control(self, field: str):
        """The shown system's control handle for a settings field (``"gamma"``, ``"variant"``,
        ``"params.m"``, ``"initial.u1"``, ``"option.compare"``, ...); KeyError if it has none."""
        return self.scenes.control(field)

    @property
    def reset(self):
        """The shown system's reset button."""
        return self.scenes.resets[self.kind]

    def reset_to_paper(self) -> None:
        self.scenes.reset_to_paper()

    def _on_scene(self) -> None:
        self.scenes.on_scene()

    def _view_for(self, title: str) -> GenericView:
        return self.scenes.view_for(title)

    def link_values(self) -> dict:
        return self.scenes.link_values()

    def open_link(self, query: str):
        return self.scenes.open_link(query)

    # runs (web.session_runs)
    traj = _part("runs", "traj")
    _installs = _part("runs", "installs")
    run_status = _part("runs", "run_status")
    runner = property(lambda self: self.runs.runner)
    status = property(lambda self: self.runs.status)
    sim_log = property(lambda self: self.runs.runner.sim_log)  # the runner's records (tests read them)
    latencies = property(lambda self: self.runs.runner.latencies)
    worker = property(lambda self: self.runs.runner.worker)

    def snapshot(self) -> dict:
        return self.runs.snapshot()

    def request(self, keep_notes: bool = False) -> None:
        self.runs.request(keep_notes)

    def install(self, traj: Trajectory) -> None:
        """Show a new trajectory (web.session_runs)."""
        self.runs.install(traj)

    def show_status(self, text: str) -> None:
        self.runs.show_status(text)

    def _show_status(self) -> None:
        self.runs.show_refusals()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        return self.runs.runner.wait_idle(timeout)

    # ---------------------------------------------------------------- the browser
    def alive(self) -> bool:
        """The browser is still there (always, for a test's shared server)."""
        return not self.closed and (self._connected is None or self._connected())

    def _on_page(self, answer: dict) -> None:
        """An answer of the page's scripts (:mod:`web.page`)."""
        if answer.get("kind") == "plots":
            busy = bool(answer.get("busy"))
            with self.lock:
                self.plots.busy = busy
                if not busy and self.traj is not None:
                    self.plots.mark(self.traj, self.t_now)
        elif answer.get("kind") == "plot width":
            try:
                width = float(answer.get("width", 0.0))
            except (TypeError, ValueError):
                return
            with self.lock:
                self.plots.set_width(width)
        elif answer.get("kind") == "renderer":
            self._on_renderer(str(answer.get("name", "")))
        else:
            self.link.on_answer(answer)

    def _on_renderer(self, name: str) -> None:
        """The page draws with ``name``: without a graphics card (software WebGL), shadows more
        than double a frame's cost (measured in headless Chromium's SwiftShader at 1400 × 900:
        3 frames a second with them, 7 without), so they start off there; the box turns them on.
        With a graphics card, the environment map lights the scene (web.lighting)."""
        self.renderer = name
        software = is_software(name)
        if self.alive():
            self.lighting.on_renderer(software)
        if software and self.shadows.value:
            self.controls.set_quietly(self.shadows, False)
            self._light()

    def _light(self) -> None:
        """The scene's default lights, casting shadows or not as the *Shadows* box says."""
        if self.client is not None and self.alive():
            self.client.scene.configure_default_lights(True, cast_shadow=bool(self.shadows.value))

    # ---------------------------------------------------------------- lifecycle
    def close(self) -> None:
        with self.lock:
            self.closed = True
        self.runs.runner.close()
        self.controls.close()
