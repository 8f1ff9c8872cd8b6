"""Shorter forms of derived matrix entries for people to read, within a time budget.

sympy's ``simplify`` takes milliseconds on the paper's entries and seconds on those of a
closed loop of several bodies (40–48 entries, 26–27 s for a panel), mostly to find no
shorter form.  What
prints or draws matrices (``nmkane matrices``, the web page's panel) simplifies each entry
within :data:`ENTRY_S` seconds and all of them within a :class:`Budget`; an entry not done in
time is shown as derived.  The limit is a timer signal, so it holds in a process's main thread
(the CLI, the web panel's child process); elsewhere the work runs without one.
"""

from __future__ import annotations

import math
import signal
import threading
import time
from collections.abc import Callable
from typing import TypeVar

__all__ = ["ENTRY_S", "PANEL_S", "Budget", "within"]

#: seconds for one entry
ENTRY_S = 4.0
#: seconds for all the entries of one printout or panel: the paper's systems and the built-in
#: open chains take 0.1–2.6 s, the slowest closed loop within it 5.4 s
PANEL_S = 8.0

T = TypeVar("T")


class _Late(Exception):
    pass


def within(seconds: float, fn: Callable[[], T], fallback: T) -> T:
    """``fn()``, or ``fallback`` when it takes longer than ``seconds`` (only in the main
    thread: elsewhere ``fn()`` without a limit)."""
    if seconds <= 0:
        return fallback
    if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "setitimer"):
        return fn()

    def late(_sig, _frame):
        raise _Late

    old = signal.signal(signal.SIGALRM, late)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return fn()
    except _Late:
        return fallback
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


class Budget:
    """The time left for a set of entries: each gets at most ``entry_s`` seconds, all of them
    together ``total_s``."""

    def __init__(self, total_s: float = PANEL_S, entry_s: float = ENTRY_S):
        self.deadline = time.monotonic() + total_s if math.isfinite(total_s) else math.inf
        self.entry_s = entry_s

    def seconds(self) -> float:
        """The time the next entry may take (≤ 0: none left)."""
        return min(self.entry_s, self.deadline - time.monotonic())

    def simplified(self, e, max_ops: int = 300):
        """``sympy.simplify(e)`` within the budget, else ``e``; entries longer than ``max_ops``
        (``count_ops``) are left as they are."""
        import sympy as sp

        if e.is_number or sp.count_ops(e) >= max_ops:
            return e
        return within(self.seconds(), lambda: sp.simplify(e), e)
