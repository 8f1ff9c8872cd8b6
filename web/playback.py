"""One page's playback: what its scene shows, when.

:class:`Playback` holds the animation's time and whether it plays, the *Playback* folder's
play button, speed, time scrubber and *Camera follows* box, and draws the frames: one per
call of :meth:`Playback.tick` (the animation thread of :mod:`web.server`), one per
:meth:`Playback.seek` (the scrubber, the keys, a test).  The camera looks at the shown
system fixed on its whole motion or following it (:mod:`web.camera`).

**Each frame whole.**  Everything drawn for one instant — the bodies' poses, rods, threads,
labels, force arrows, ghosts, the camera when it follows, and on a refresh the plot markers,
scrubber and readouts — is written in one ``atomic()`` block of viser
(:meth:`Playback.frame`): it leaves the server as one websocket message
(:func:`web.viser_compat.whole_windows`), and the page shows it in one frame
(:data:`web.viser_compat.WHOLE_FRAMES`).
"""

from __future__ import annotations

from . import viser_compat as compat
from .labels import LabelLayout


class Playback:
    """The time shown by one session (``session``: a :class:`web.session.MechanismApp`, whose
    ``traj``, ``views``, ``kind``, ``system_view``, ``camera``, ``plots``, ``lock``,
    ``alive()``, ``closed``, ``client`` and ``target`` it reads)."""

    def __init__(self, session):
        self.session = session
        self.playing = True
        self.t_now = 0.0
        self.shown_t: float | None = None  # the time the slow-rate parts last showed
        self.labels = LabelLayout()  # which corner each 3D label holds (web.labels)

    # ---------------------------------------------------------------- the folder
    def add_controls(self, gui, controls) -> None:
        """The play button, speed, time scrubber and *Camera follows* box (in the folder being
        built); ``controls``: the session's :class:`~web.controls.ControlPanel`."""
        self.controls = controls
        self.play = gui.add_button("❚❚ Pause")
        # log: a 0.03 s benchmark plays at 0.02×, a 300 s run at 5× (the systems' showcase speeds)
        self.speed = controls.number("Speed ×", 1.0, 0.01, 20.0, 0.01, log=True)
        self.time = controls.number("Time t [s]", 0.0, 0.0, 20.0, 0.01, unit="s", marks=False)
        self.follow = gui.add_checkbox("Camera follows", initial_value=True)

    def wire(self, view_reset, fit_view) -> None:
        """Playback controls move the shown time and the camera; none of them re-simulates."""
        c = self.controls
        self.play.on_click(lambda _: self.set_playing(not self.playing))
        c.on_change(self.speed, lambda: None)
        c.on_change(self.time, self.on_time)
        view_reset.on_click(lambda _: self.reset_view())
        fit_view.on_click(lambda _: self.fit())
        c.on_change(self.follow, self.on_follow)

    # ---------------------------------------------------------------- actions
    def set_playing(self, playing: bool) -> None:
        self.playing = bool(playing)
        self.play.label = "❚❚ Pause" if self.playing else "▶ Play"

    def fit(self) -> None:
        """Frame the mechanism as it is at the shown time (not the paths it traced), from the side
        the viewer looks from now, in the part of the view the panel leaves free; a following
        camera goes on following it from there."""
        s = self.session
        with s.lock:
            view = s.system_view
            traj = s.traj
            if traj is None or traj.kind != view.kind:
                return
            vp = s.camera.viewport()
            plan = view.plan = view.camera_plan(vp)
            now = view.fit_now(vp, s.camera.direction())
            if plan is None or now is None:
                return
            look_at, position = now
            following = bool(self.follow.value)
            if following:  # follow from this view
                plan.shift = look_at - view._centre()
                plan.offset = position - look_at
            s.camera.place(look_at, position, following=following)

    def reset_view(self) -> None:
        """The system's first view: fixed on its parts' whole motion, or following them when
        that would show them much smaller (:mod:`web.camera`)."""
        with self.session.lock:
            self.look(follow=None)

    def on_follow(self) -> None:
        """The *Camera follows* box: ticked, the camera follows the mechanism (from the view the
        plan keeps); unticked, it stays where it is."""
        s = self.session
        with s.lock:
            if bool(self.follow.value):
                self.look(follow=True)
            else:
                s.camera.hold()

    def look(self, follow: bool | None) -> None:
        """Frame the shown system as its first view does (None: fixed on its parts' whole
        motion or following them, as :class:`web.camera.CameraPlan` decides) or following it
        (True); the *Camera follows* box says which."""
        s = self.session
        view = s.system_view
        traj = s.traj
        if traj is None or traj.kind != view.kind:
            return
        if follow is None or view.plan is None:
            view.plan = view.camera_plan(s.camera.viewport())
        plan = view.plan
        if plan is None:
            return
        follow = plan.follows if follow is None else follow
        if bool(self.follow.value) != follow:
            self.controls.set_quietly(self.follow, follow)
        if follow:
            target = view.follow_target()
            s.camera.place(target, target + plan.offset, following=True)
        else:
            s.camera.place(*plan.motion, following=False)

    def seek(self, t: float) -> None:
        """Show time t (the scrubber, the keys, or a test): one whole frame."""
        s = self.session
        with s.lock:
            self.t_now = float(t)
            if s.traj is not None:
                self.t_now = min(max(self.t_now, 0.0), s.traj.t_end)
                with self.frame():
                    self.show_time(self.t_now)
                    self.refresh(force=True)

    def on_time(self) -> None:
        self.seek(float(self.time.value))  # a person (or a test) typed a time or moved the scrubber

    def on_install(self, traj, first_sight: bool) -> None:
        """A new run is shown (in the session's install): the time kept within it, the first
        run of a system framed, the scrubber's range."""
        self.t_now = min(self.t_now, traj.t_end)
        if first_sight:
            self.show_time(self.t_now)
            self.look(follow=None)
        self.time.set_range(0.0, max(traj.t_end, 0.01))

    # ---------------------------------------------------------------- frames
    def frame(self):
        """The scope of one frame's writes: viser sends them as one batch."""
        return self.session.target.atomic()

    def show_time(self, t_now: float) -> None:
        """Put every node where the state at time t_now puts it (and the camera, if following)."""
        s = self.session
        traj = s.traj
        if traj is None:
            return
        view = s.views[traj.kind]
        view.pose(traj, t_now)
        if traj.kind != s.kind:
            return
        if self.follow.value:
            s.camera.follow(view.follow_target())
        self.labels.apply(view.label_points(), s.camera.view())  # labels that do not cover each other

    def refresh(self, force: bool = False) -> None:
        """The slow-rate part of a frame: plot markers, scrubber, readouts."""
        s = self.session
        traj = s.traj
        if traj is None:
            return
        if not force and self.shown_t == self.t_now:
            return  # nothing moved
        self.shown_t = self.t_now
        s.plots.mark(traj, self.t_now)
        self.time.display(round(min(self.t_now, self.time.max), 2))
        s.views[traj.kind].readouts(traj, self.t_now)

    def tick(self, dt_wall: float, refresh: bool) -> None:
        """One animation frame (called by the animation thread): the time advanced when
        playing, then everything it shows written as one batch."""
        s = self.session
        if s.closed:
            return
        with s.lock:
            traj = s.traj
            if traj is None or not s.alive():
                return
            if self.playing:
                self.t_now += dt_wall * float(self.speed.value)
                if self.t_now > traj.t_end:
                    self.t_now = 0.0 if traj.t_end > 0 else traj.t_end
            with compat.dead_writes_allowed(s.client), self.frame():  # a frame begun before the browser left
                self.show_time(self.t_now)
                if refresh:
                    self.refresh()
