"""Run scheduling: a control change becomes a new trajectory on screen.

A control change snapshots the controls (on the caller's thread: browser callbacks read
live values) and hands the request to the session's :class:`~web.worker.LatestWorker`,
which re-simulates off the GUI thread with the compiled kernels (bursts coalesce, the
newest wins) and hands the :class:`Trajectory` to the session to install.  With
``sync=True`` the caller's thread simulates (deterministic tests).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from nmkane_core.errors import InputError

from . import geometry as geo
from .worker import LatestWorker

TIME_LIMIT_S = 10.0  # a run that takes longer stops with status 'timeout'


@dataclass
class Trajectory:
    """What a session animates: the runs of one request, prepared for display."""

    kind: str  # the view's kind (the system name)
    request: dict
    runs: dict  # label -> nmkane_core Run (first = main)
    params: dict
    plots: dict  # plot key -> plots.Curves
    t_request: float  # perf_counter when the controls were read
    compute_s: float = 0.0
    installed_at: float = 0.0
    seq: int = 0

    @property
    def main(self):
        return next(iter(self.runs.values()))

    @property
    def t_end(self) -> float:
        return max(float(r.t[-1]) for r in self.runs.values())

    def row(self, label: str, t_now: float) -> dict:
        run = self.runs[label]
        k = geo.index_at(run.t, t_now)
        return {n: float(v[k]) for n, v in run.state.items()}


class Runner:
    """Turns requests into trajectories for one session.

    ``session`` provides ``closed``, ``view_of(kind)``, ``current_kind()``, ``install(traj)``
    and ``show_status(text)``; ``simulate`` is :func:`nmkane_core.run.simulate.simulate` (or a
    test's stand-in)."""

    def __init__(self, session, simulate: Callable, *, sync: bool = False):
        self.session = session
        self._simulate = simulate
        self.sim_log: list[dict] = []  # settings of every simulation (tests read them)
        self.latencies: list[float] = []  # control change -> new trajectory installed, s
        self.quiet = False  # while resetting: one request at the end
        self._seq = 0
        self.worker = None if sync else LatestWorker(self.compute)

    def next_request(self, kind: str, settings: dict, options: dict) -> dict:
        self._seq += 1
        return {
            "kind": kind,
            "seq": self._seq,
            "t_request": time.perf_counter(),
            "settings": settings,
            "options": options,
        }

    def submit(self, req: dict) -> None:
        if self.quiet or self.session.closed:
            return
        if self.worker is None:
            self.compute(req)
        else:
            self.worker.submit(req)

    def superseded(self) -> bool:
        """A newer request is waiting (or the browser left): stop the run in progress."""
        return self.session.closed or (self.worker is not None and self.worker.pending is not None)

    def _run(self, settings: dict):
        self.sim_log.append(settings)
        return self._simulate(settings, progress=False, time_limit=TIME_LIMIT_S, cancel=self.superseded)

    def compute(self, req: dict) -> None:
        """Simulate a request and install the result (the worker thread, or the caller's)."""
        t0 = time.perf_counter()
        view = self.session.view_of(req["kind"])
        try:
            runs = {label: self._run(s) for label, s in view.runs(req["settings"], req["options"]).items()}
            plots = view.curves(runs)
        except InputError as e:
            self.session.show_status(f"**input refused** — {e}  \nthe previous motion keeps playing")
            return
        except Exception as e:  # never a frozen panel: say what happened
            self.session.show_status(f"**failed** — {type(e).__name__}: {e}")
            raise
        params = dict(next(iter(runs.values())).settings["params"])
        traj = Trajectory(
            req["kind"], req, runs, params, plots, req["t_request"], compute_s=time.perf_counter() - t0, seq=req["seq"]
        )
        if self.superseded() or req["kind"] != self.session.current_kind():
            return  # a newer request follows: show that one
        self.session.install(traj)

    def record_install(self, traj: Trajectory) -> None:
        traj.installed_at = time.perf_counter()
        self.latencies.append(traj.installed_at - traj.t_request)

    def wait_idle(self, timeout: float = 30.0) -> bool:
        return True if self.worker is None else self.worker.wait_idle(timeout)

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()
