"""Re-simulation off the GUI thread: the newest request wins.

A slider drag fires one event per step (viser sends every step) and browser callbacks run
concurrently on viser's thread pool, so callbacks only *submit* a snapshot of the
controls.  One thread per session runs the newest pending request; requests that arrive
while it computes replace each other, and a short debounce lets a burst of programmatic
changes (a reset sets a dozen controls) settle into one run.
"""

from __future__ import annotations

import threading
import time
import traceback
from collections.abc import Callable
from typing import Any


class LatestWorker:
    """Runs ``fn(request)`` for the newest submitted request only."""

    def __init__(self, fn: Callable[[Any], None], debounce: float = 0.01, name: str = "nmkane-resim"):
        self.fn, self.debounce = fn, debounce
        self.cv = threading.Condition()
        self.pending: Any = None
        self.busy = False
        self.closed = False
        self.runs = 0
        self.thread = threading.Thread(target=self._run, daemon=True, name=name)
        self.thread.start()

    def submit(self, request: Any) -> None:
        with self.cv:
            self.pending = request
            self.cv.notify_all()

    def _run(self) -> None:
        while True:
            with self.cv:
                while self.pending is None and not self.closed:
                    self.cv.wait()
                if self.closed:
                    return
                self.busy = True
            if self.debounce:
                time.sleep(self.debounce)  # let a burst settle; the newest is kept
            with self.cv:
                request, self.pending = self.pending, None
            try:
                if request is not None:
                    self.fn(request)
                    self.runs += 1
            except Exception:  # a display worker must survive anything
                traceback.print_exc()
            finally:
                with self.cv:
                    self.busy = False
                    self.cv.notify_all()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        """Block until nothing is pending or running (tests, screenshots)."""
        end = time.monotonic() + timeout
        with self.cv:
            while self.pending is not None or self.busy:
                left = end - time.monotonic()
                if left <= 0:
                    return False
                self.cv.wait(left)
        return True

    def close(self) -> None:
        with self.cv:
            self.closed = True
            self.cv.notify_all()
        if threading.current_thread() is not self.thread:
            self.thread.join(5)
