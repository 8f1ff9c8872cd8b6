"""One page's runs: the controls read into a request, the request run, the run shown.

:class:`SessionRuns` snapshots the shown system's controls into a request (on the caller's
thread: browser callbacks read live values), hands it to the :class:`~web.runs.Runner`
(a worker thread re-simulates, bursts coalesce, the newest wins), installs the trajectory it
gets back — the views' geometry, traces, plots, matrices and summary, as one batch — and
keeps the status line (the run's status, the boxes' refusals under it).
"""

from __future__ import annotations

from collections.abc import Callable

from . import stability
from . import viser_compat as compat
from .controls import settings_from
from .panel import status_text
from .runs import Runner, Trajectory

FIRST_STATUS = "computing … (the first run loads the compiled kernels)"


class SessionRuns:
    """The runs of one session (``session``: a :class:`web.session.MechanismApp`; the
    :class:`~web.runs.Runner` calls its ``install`` and ``show_status``)."""

    def __init__(self, session, simulate: Callable, *, sync: bool = False):
        self.session = session
        self.runner = Runner(session, simulate, sync=sync)
        self.traj: Trajectory | None = None  # the run shown
        self.installs = 0
        self.run_status = FIRST_STATUS

    def add_status(self, gui) -> None:
        """The status line (in the panel being built)."""
        self.status = gui.add_markdown(self.run_status)

    # ---------------------------------------------------------------- requests
    def snapshot(self) -> dict:
        """The controls now (read on the caller's thread: browser callbacks read live values)."""
        s = self.session
        view = s.system_view
        settings, options = settings_from(view.core, s.sim_controls[view.kind], s.controls.value)
        return self.runner.next_request(view.kind, settings, options)

    def request(self, keep_notes: bool = False) -> None:
        s = self.session
        if self.runner.quiet or s.closed:
            return
        if not keep_notes:
            s.controls.note("link", [])  # a link's refusals last until the next change
        self.runner.submit(s.snapshot())
        s.link.update()

    # ---------------------------------------------------------------- the status line
    def show_status(self, text: str) -> None:
        """The run's status line (the refusals of the boxes are added under it)."""
        self.run_status = text
        self.show_refusals()

    def show_refusals(self) -> None:
        s = self.session
        if s.alive():
            self.status.content = "  \n".join([self.run_status, *s.controls.refusal_lines()])

    # ---------------------------------------------------------------- installing
    def install(self, traj: Trajectory) -> None:
        """Show a new trajectory: geometry that depends on it, trace, plots, summary (one
        batch, sent at once)."""
        s = self.session
        view = s.views[traj.kind]
        playback = s.playback
        with s.lock, compat.dead_writes_allowed(s.client):  # it may leave while this is sent, not before
            if not s.alive():  # the browser left while this was computed
                return
            with playback.frame():
                view.install(traj)
                s.matrices.show(view.system, view.matrices_variant(traj.request["settings"]))
                self.traj = traj
                first_sight = getattr(view, "fit_pending", False) and traj.kind == s.kind
                if first_sight:
                    view.fit_pending = False  # first sight of this system: frame it
                playback.on_install(traj, first_sight)
                self.installs += 1
                s.plots.write(traj, playback.t_now)
                stability.update(s, traj)  # the run's value marked on the eigenvalue plot
                playback.show_time(playback.t_now)
                playback.refresh(force=True)
                self.runner.record_install(traj)
                s.show_status(status_text(traj, self.installs))
                if traj.kind in s.legends:
                    s.legends[traj.kind].content = view.legend(traj)
        s.target.flush()  # out now, not at the next 1/60 s window
