"""One browser's page: its controls, scene, camera and trajectory, wired together.

Every connected browser gets its own :class:`MechanismApp`, so students exploring at once
do not change each other's view.  Every system is shown by the same
:class:`~web.generic.GenericView` (one scene, one simulation folder and one set of plots
per system, built when it is first chosen, the chosen one visible); the parts live in
:mod:`web.controls` (handles and their guard), :mod:`web.runs` (re-simulation on a control
change), :mod:`web.panel` (plots, summary, status, matrices) and :mod:`web.camera`.  The
animation thread of :mod:`web.server` calls :meth:`MechanismApp.tick`.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable

import viser

from nmkane_core.run.simulate import simulate as core_simulate

from . import stability
from .camera import CameraRig
from .controls import Control, ControlPanel, settings_from
from .export_button import ExportButton
from .forces import ForcePanel
from .generic import GenericView, scene_choices
from .keys import add_keys
from .lighting import Lighting
from .link import Link, LinkPanel, read_link, read_system
from .numbers import HIDE_SLIDER_BOXES, ExpressionField, NumberField
from .page import PageBridge, is_software
from .panel import MatricesPanel, PlotPanel, status_text
from .runs import Runner, Trajectory
from .study import StudyPanel

SHADOWS_HINT = (
    "The bodies' shadows on the ground. Off by itself where the browser draws without a graphics "
    "card (software WebGL), where they more than double the cost of a frame."
)


def racing_a_leave(client):
    """The scope of writes that may race the browser's leaving: a page being built, a run
    being installed, an animation frame.  Messages queued there after viser closed the connection are dropped
    with it, harmless, and viser's warning about them is silenced; it is kept for every other
    write (a run installed after the browser left would still raise it).  ``client`` None (a
    test's shared server) or a viser other than 1.1: no scope."""
    try:
        return client._websock_connection.get_message_buffer().sanctioned_dead_writes()
    except AttributeError:
        return contextlib.nullcontext()


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
        self.traj: Trajectory | None = None
        self.t_now = 0.0
        self.playing = True
        self.closed = False
        self._installs = 0
        self.renderer = ""  # the page's WebGL renderer, once it has said (web.page)
        self.lighting = Lighting(self.client)  # plain lights until the page says a graphics card draws it
        self.run_status = "computing … (the first run loads the compiled kernels)"
        self._shown_t: float | None = None
        self.views: dict[str, GenericView] = {}
        self.choices = scene_choices()  # dropdown title -> system name
        first = next((t for t, n in self.choices.items() if n == scene), None) if scene else None
        first = first or next(iter(self.choices))
        self.camera = CameraRig(self.client, self.alive)
        self.runner = Runner(self, simulate, sync=sync)
        self._build_gui(first)
        if self.client is not None:
            self.client.camera.on_update(lambda cam: self.camera.on_report(cam))
        self._on_scene()
        self.link.start()  # the page says which link it was opened with; then its address follows the page
        self.bridge.help_plots()
        self.bridge.ask_renderer()  # software WebGL: shadows off (self._on_page)

    # ---------------------------------------------------------------- GUI
    def _build_gui(self, first: str) -> None:
        gui = self.gui
        gui.add_html(HIDE_SLIDER_BOXES)  # viser's own slider boxes misread typing: ours are above them
        self.controls = ControlPanel(gui, self._show_status, self.lock)
        gui.add_markdown("Nonminimal Kane's equations — Bajodah, Hodges & Chen (2005)")
        titles = tuple(self.choices)
        self.scene_choice = gui.add_dropdown("Scene", options=titles, initial_value=first)
        self.status = gui.add_markdown(self.run_status)
        self.bridge = PageBridge(gui, self.client, self._on_page)
        self.link = LinkPanel(gui, self)

        with self._form("Playback"):
            self.play = gui.add_button("❚❚ Pause")
            # log: a 0.03 s benchmark plays at 0.02×, a 300 s run at 5× (the systems' showcase speeds)
            self.speed = self.controls.number("Speed ×", 1.0, 0.01, 20.0, 0.01, log=True)
            self.time = self.controls.number("Time t [s]", 0.0, 0.0, 20.0, 0.01, unit="s", marks=False)
            self.follow = gui.add_checkbox("Camera follows", initial_value=True)
            self.shadows = gui.add_checkbox("Shadows", initial_value=True, hint=SHADOWS_HINT)
            self.view_reset = gui.add_button("Reset view")
            self.fit_view = gui.add_button("Fit view")
            self.export = ExportButton(gui, self)  # the shown run as one offline HTML file
            self.keys = add_keys(gui, self)

        self.sim_controls: dict[str, dict] = {}  # kind -> {Control: handle}
        self.folders: dict[str, viser.GuiFolderHandle] = {}
        self.legends: dict[str, viser.GuiMarkdownHandle] = {}
        self.resets: dict[str, viser.GuiButtonHandle] = {}
        view = GenericView(self.scene, self.choices[first])
        self.views[view.kind] = self.system_view = view  # the chosen system's view
        self._add_view_gui(view, visible=True)

        with gui.add_folder("Plots and summary") as self.plots_folder:
            self.plots = PlotPanel(gui, self.views)
            self.summary = self.plots.summary
            self.plot_handles = self.plots.handles

        with gui.add_folder("Derived matrices", expand_by_default=False):
            self.matrices = MatricesPanel(gui, self.lock, self.alive, lambda: racing_a_leave(self.client))

        # wiring: every simulation input re-simulates; playback controls do not
        self.scene_choice.on_update(lambda _: self._on_scene())
        self.play.on_click(lambda _: self.set_playing(not self.playing))
        self.controls.on_change(self.speed, lambda: None)
        self.controls.on_change(self.time, self._on_time)
        self.view_reset.on_click(lambda _: self.reset_view())
        self.fit_view.on_click(lambda _: self.fit())
        self.controls.on_change(self.follow, lambda: self._look(follow=bool(self.follow.value)))
        self.controls.on_change(self.shadows, self._light)
        with self._form("Γ study", expand_by_default=False):  # web/study.py; follows the scene itself
            self.study = StudyPanel(gui, self)

    def _add_view_gui(self, view, visible: bool, order: float | None = None) -> None:
        """A view's simulation folder (controls, parameters, reset button), wired to re-simulate."""
        gui = self.gui
        self.folders[view.kind] = folder = self._form(view.folder, visible=visible, order=order)
        with folder:
            core = view.core
            text = [f"*{core.description}*"] if core.description else []
            text += [f"**What to try:** {core.what_to_try}"] if core.what_to_try else []
            if text:
                gui.add_markdown("  \n".join(text))
            handles: dict[Control, object] = {}
            for c in view.controls:
                if c.field.startswith("initial.") and not any(k.field.startswith("initial.") for k in handles):
                    gui.add_markdown("**Initial values** (t = 0; the dependent ones follow from the constraints)")
                handles[c] = self.controls.add(c)
                if c.field == "option.compare":
                    self.legends[view.kind] = gui.add_markdown("")  # which colour is which run
            if view.forces.declared:
                view.force_panel = ForcePanel(gui, view.forces)
            with gui.add_folder(view.params_folder, expand_by_default=False):
                params = {c.attr: self.controls.add(c) for c in view.param_controls}
            self.resets[view.kind] = gui.add_button(view.reset_label)
        handles.update({c: params[c.attr] for c in view.param_controls})
        self.sim_controls[view.kind] = handles
        self._keep_the_ghost(handles)
        for h in handles.values():
            self.controls.on_change(h, self.request)
        self.resets[view.kind].on_click(lambda _: self.reset_to_paper())

    def _keep_the_ghost(self, handles: dict) -> None:
        """Choosing as the model the one shown as the ghost swaps them: the ghost then shows
        the model shown before (rather than silently vanishing)."""
        by_field = {c.field: h for c, h in handles.items()}
        variant, compare = by_field.get("variant"), by_field.get("option.compare")
        if variant is None or compare is None:
            return
        before = {"variant": variant.value}

        def swap(_event) -> None:
            new, old = variant.value, before["variant"]
            before["variant"] = new
            if compare.value == new and old != new:
                self.controls.set_quietly(compare, old)

        variant.on_update(swap)  # before the re-simulation's callback: the run sees the swapped compare

    def _form(self, label: str, **kw) -> viser.GuiFolderHandle:
        """A folder whose boxes apply what is typed on Enter (viser's form)."""
        form = self.gui.add_form(label, **kw)
        form.on_submit(lambda _: self.controls.submit())
        return form

    def _view_for(self, title: str) -> GenericView:
        """The view of a dropdown entry (built on first use)."""
        name = self.choices[title]
        kind = name
        if kind not in self.views:
            view = GenericView(self.scene, name)
            self.views[kind] = view
            first = next(iter(self.folders.values()))
            self._add_view_gui(view, visible=False, order=getattr(first, "order", None))
            with self.plots_folder:
                self.plots.add_view(self.gui, view)
                stability.attach(self, view)  # eigenvalue plot of a declared stability sweep
        return self.views[kind]

    @property
    def kind(self) -> str:
        return self.system_view.kind

    def current_kind(self) -> str:
        return self.system_view.kind

    def view_of(self, kind: str):
        return self.views[kind]

    def control(self, field: str):
        """The shown system's control handle for a settings field (``"gamma"``, ``"variant"``,
        ``"params.m"``, ``"initial.u1"``, ``"option.compare"``, ...); KeyError if it has none."""
        for c, h in self.sim_controls[self.kind].items():
            if c.field == field:
                return h
        raise KeyError(f"{self.system_view.system} has no control for {field!r}")

    @property
    def reset(self):
        """The shown system's reset button."""
        return self.resets[self.kind]

    def alive(self) -> bool:
        """The browser is still there (always, for a test's shared server)."""
        return not self.closed and (self._connected is None or self._connected())

    # the runner's records (tests read them)
    sim_log = property(lambda self: self.runner.sim_log)
    latencies = property(lambda self: self.runner.latencies)
    worker = property(lambda self: self.runner.worker)

    # ---------------------------------------------------------------- control actions
    def set_playing(self, playing: bool) -> None:
        self.playing = bool(playing)
        self.play.label = "❚❚ Pause" if self.playing else "▶ Play"

    def fit(self) -> None:
        """Frame the whole motion of the run (every path travelled) in the part of the view the
        panel leaves free, and stop following (else the camera would leave that view)."""
        with self.lock:
            self._look(follow=False)

    def reset_view(self) -> None:
        """The system's first view: its bodies followed, or its whole motion when that is small."""
        with self.lock:
            self._look(follow=None)

    def _look(self, follow: bool | None) -> None:
        """Frame the shown system, following it (True), fixed on its whole motion (False), or
        as its first view does (None); the *Camera follows* box says which."""
        view = self.system_view
        traj = self.traj
        if traj is None or traj.kind != view.kind:
            return
        plan = view.plan = view.camera_plan(self.camera.viewport())
        if plan is None:
            return
        follow = plan.follows if follow is None else follow
        if bool(self.follow.value) != follow:
            self.controls.set_quietly(self.follow, follow)
        if follow:
            target = view.follow_target()
            self.camera.place(target, target + plan.offset, following=True)
        else:
            self.camera.place(*plan.whole, following=False)

    def seek(self, t: float) -> None:
        """Show time t (the scrubber, or a test)."""
        with self.lock:
            self.t_now = float(t)
            if self.traj is not None:
                self.t_now = min(max(self.t_now, 0.0), self.traj.t_end)
                self.show_time(self.t_now)
                self._refresh(force=True)

    def _on_time(self) -> None:
        self.seek(float(self.time.value))  # a person (or a test) typed a time or moved the scrubber

    def reset_to_paper(self) -> None:
        """Every control of the current scene back to its default (the system's showcase, e.g. the
        paper's values, where it declares one): one re-simulation."""
        self.runner.quiet = True
        try:
            for c, h in self.sim_controls[self.kind].items():
                h.value = c.default
        finally:
            self.runner.quiet = False
        self.request()

    def _on_scene(self) -> None:
        with self.lock:
            self.system_view = self._view_for(self.scene_choice.value)
        for kind, folder in self.folders.items():
            folder.visible = kind == self.kind
        for v in self.views.values():
            v.root.visible = v is self.system_view
        self.plots.show_kind(self.kind)
        self.speed.value = self.system_view.speed
        self._look(follow=None)
        self.request()

    # ---------------------------------------------------------------- simulation
    def snapshot(self) -> dict:
        """The controls now (read on the caller's thread: browser callbacks read live values)."""
        view = self.system_view
        settings, options = settings_from(view.core, self.sim_controls[view.kind], self.controls.value)
        return self.runner.next_request(view.kind, settings, options)

    def request(self, keep_notes: bool = False) -> None:
        if self.runner.quiet or self.closed:
            return
        if not keep_notes:
            self.controls.note("link", [])  # a link's refusals last until the next change
        self.runner.submit(self.snapshot())
        self.link.update()

    # ---------------------------------------------------------------- the page
    def _on_page(self, answer: dict) -> None:
        """An answer of the page's scripts (:mod:`web.page`)."""
        if answer.get("kind") == "plots":
            busy = bool(answer.get("busy"))
            with self.lock:
                self.plots.busy = busy
                if not busy and self.traj is not None:
                    self.plots.mark(self.traj, self.t_now)
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

    # ---------------------------------------------------------------- links
    def link_values(self) -> dict:
        """The shown system's controls and their values (what a link carries)."""
        return {c: self.controls.value(h) for c, h in self.sim_controls[self.kind].items()}

    def open_link(self, query: str) -> Link:
        """Build the page a link asks for (``?system=…&dt=…``): its system, then its values —
        each box reads its value as if it were typed, a bad one is refused beside its box and
        the rest are applied — and one run."""
        system, refused = read_system(query, tuple(self.choices.values()))
        self.runner.quiet = True
        try:
            if system is not None and system != self.kind:
                self.scene_choice.value = next(t for t, n in self.choices.items() if n == system)
            link = read_link(query, tuple(self.sim_controls[self.kind]), self.system_view.core.option)
            handles = self.sim_controls[self.kind]
            for c, v in link.values.items():
                if isinstance(handles[c], (NumberField, ExpressionField)):
                    handles[c].text.value = str(v)  # read and checked as typed (at once: set from Python)
                else:
                    handles[c].value = v
        finally:
            self.runner.quiet = False
        self.controls.note("link", refused + link.refused)
        self.request(keep_notes=True)
        return link

    def show_status(self, text: str) -> None:
        """The run's status line (the refusals of the boxes are added under it)."""
        self.run_status = text
        self._show_status()

    def _show_status(self) -> None:
        if self.alive():
            self.status.content = "  \n".join([self.run_status, *self.controls.refusal_lines()])

    def install(self, traj: Trajectory) -> None:
        """Show a new trajectory: geometry that depends on it, trace, plots, summary."""
        view = self.views[traj.kind]
        with self.lock, racing_a_leave(self.client):  # it may leave while this is sent, not before
            if not self.alive():  # the browser left while this was computed
                return
            with self._atomic():
                view.install(traj)
                self.matrices.show(view.system, view.matrices_variant(traj.request["settings"]))
                self.traj = traj
                self.t_now = min(self.t_now, traj.t_end)
                if getattr(view, "fit_pending", False) and traj.kind == self.kind:
                    view.fit_pending = False  # first sight of this system: frame it
                    self.show_time(self.t_now)
                    self._look(follow=None)
                self.time.set_range(0.0, max(traj.t_end, 0.01))
                self._installs += 1
                self.plots.write(traj, self.t_now)
                stability.update(self, traj)  # the run's value marked on the eigenvalue plot
                self.show_time(self.t_now)
                self._refresh(force=True)
                self.runner.record_install(traj)
                self.show_status(status_text(traj, self._installs))
                if traj.kind in self.legends:
                    self.legends[traj.kind].content = view.legend(traj)
        self.target.flush()  # out now, not at the next 1/60 s window

    @contextlib.contextmanager
    def _atomic(self):
        with self.target.atomic():
            yield

    # ---------------------------------------------------------------- animation
    def show_time(self, t_now: float) -> None:
        """Put every node where the state at time t_now puts it (and the camera, if following)."""
        traj = self.traj
        if traj is None:
            return
        view = self.views[traj.kind]
        view.pose(traj, t_now)
        if self.follow.value and traj.kind == self.kind:
            self.camera.follow(view.follow_target())

    def _refresh(self, force: bool = False) -> None:
        """The slow-rate part of a frame: plot markers, scrubber, readouts."""
        traj = self.traj
        if traj is None:
            return
        if not force and self._shown_t == self.t_now and not self.plots.phase_lags(traj, self.t_now):
            return  # nothing moved (a portrait throttled at a seek is drawn once its second has passed)
        self._shown_t = self.t_now
        self.plots.mark(traj, self.t_now)
        self.time.display(round(min(self.t_now, self.time.max), 2))
        self.views[traj.kind].readouts(traj, self.t_now)

    def tick(self, dt_wall: float, refresh: bool) -> None:
        """One animation frame (called by the animation thread)."""
        if self.closed:
            return
        with self.lock:
            traj = self.traj
            if traj is None or not self.alive():
                return
            if self.playing:
                self.t_now += dt_wall * float(self.speed.value)
                if self.t_now > traj.t_end:
                    self.t_now = 0.0 if traj.t_end > 0 else traj.t_end
            with racing_a_leave(self.client):  # a frame begun before the browser left
                with self._atomic():
                    self.show_time(self.t_now)
                if refresh:
                    self._refresh()

    # ---------------------------------------------------------------- lifecycle
    def wait_idle(self, timeout: float = 30.0) -> bool:
        return self.runner.wait_idle(timeout)

    def close(self) -> None:
        with self.lock:
            self.closed = True
        self.runner.close()
        self.controls.close()
