"""Number boxes that read what was typed, and say so beside the box when they cannot.

viser's own number widgets (``add_number`` and the box beside ``add_slider``) are Mantine
NumberInputs: they drop what they cannot parse character by character (observed in the
page: ``1e6`` became 16, ``-1e1`` −11, ``1,5`` 15, ``abc`` an empty box) and send the
result, so the server never sees what was typed.  A :class:`NumberField` is therefore a
text box read by :func:`parse_number` (decimal and scientific notation, nothing else),
above a slider whose own box is hidden (:data:`HIDE_SLIDER_BOXES`, a style sheet the page
gets once), and a message line under both that says what was refused and why; it is
cleared as soon as the value is good again.

A quantity spanning decades sits on a log slider, but is typed and shown in its own units
(Δt in s, a mass in kg); the slider's marks are round values in those units.

viser sends a text box's content on every keystroke, so a typed value is applied when
the person presses Enter (the boxes live in a form: :meth:`NumberField.submit`) or stops
typing for :data:`PAUSE_S` (:class:`Deadlines`).  A value set from Python (a test, a link,
a reset) applies at once.
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections.abc import Callable
from typing import Any

PAUSE_S = 1.0  # a typed value applies after this long without a keystroke (or on Enter)
SUBMIT_DELAY_S = 0.15  # Enter: wait for the last keystroke's message (viser throttles them to 50 ms)
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?")
_MINUS = str.maketrans({"\u2212": "-", "\u2013": "-", "\u2012": "-"})  # the page writes −10 with U+2212

# the box viser puts beside every slider misreads what is typed: hidden, a text box is above
HIDE_SLIDER_BOXES = (
    "<style>.mantine-Slider-root + .mantine-NumberInput-root{display:none !important}"
    ".mantine-Slider-root{margin-bottom:0.85em}"  # room for the marks' labels under the slider
    ".nmk-msg{color:#b3261e;font-size:0.8em;line-height:1.3;padding:0 0.75em 0.4em}</style>"
)


def parse_number(text: Any) -> float:
    """The number in ``text`` as a person types it — ``0.001``, ``1e-3``, ``-1e1``,
    ``2.5E+2``, ``.5``, ``−2`` (the page's own minus sign) — or ValueError saying what
    cannot be read (a comma, a letter, nothing, a value too large for a float)."""
    if not isinstance(text, str):
        raise ValueError(f"{text!r} is not text")
    s = text.strip().translate(_MINUS)
    if not s:
        raise ValueError("the box is empty: type a number")
    if "," in s and _NUMBER.fullmatch(s.replace(",", ".", 1)):
        raise ValueError(f"{text!r}: write the decimal point as a point ({s.replace(',', '.', 1)})")
    if not _NUMBER.fullmatch(s):
        raise ValueError(f"{text!r} is not a number (numbers look like 0.001, 1e-3, -10, 2.5E+2)")
    x = float(s)
    if not math.isfinite(x):
        raise ValueError(f"{text!r} is too large for a number")
    return x


def fmt(v: float) -> str:
    """A value as the box shows it: the shortest text that reads back as the same number
    within 12 significant digits (0.001, 5, 2.5e-05, -10)."""
    s = format(float(v), ".12g")
    return "0" if s == "-0" else s


def round_sig(v: float, digits: int) -> float:
    return float(f"{v:.{digits}g}")


def log_marks(lo: float, hi: float) -> tuple[tuple[float, str], ...]:
    """Slider marks (in log10 units) at the round values between lo and hi (> 0): the
    decades (every other one when there are many), else the ends."""
    a, b = math.log10(lo), math.log10(hi)
    ks = list(range(math.ceil(a - 1e-9), math.floor(b + 1e-9) + 1))
    if len(ks) > 6:
        ks = ks[:: math.ceil(len(ks) / 5)]
    if len(ks) < 2:
        return ((a, fmt(round_sig(lo, 2))), (b, fmt(round_sig(hi, 2))))
    return tuple((float(k), fmt(10.0**k)) for k in ks)


def linear_marks(lo: float, hi: float) -> tuple[tuple[float, str], ...]:
    """Marks at the ends (and at 0 when it lies well inside), written as numbers are typed."""
    out = [(lo, fmt(round_sig(lo, 4))), (hi, fmt(round_sig(hi, 4)))]
    if lo < 0 < hi and min(-lo, hi) > 0.15 * (hi - lo):
        out.insert(1, (0.0, "0"))
    return tuple(out)


class Deadlines:
    """Calls a key's function once its deadline has passed (scheduling a key again moves
    its deadline): typed values apply when the typing pauses.  One thread per session."""

    def __init__(self) -> None:
        self._cv = threading.Condition()
        self._due: dict[Any, tuple[float, Callable[[], None]]] = {}
        self._closed = False
        self._thread: threading.Thread | None = None

    def schedule(self, key: Any, delay: float, fn: Callable[[], None]) -> None:
        with self._cv:
            if self._closed:
                return
            self._due[key] = (time.monotonic() + delay, fn)
            if self._thread is None:
                self._thread = threading.Thread(target=self._run, daemon=True, name="nmkane-typing")
                self._thread.start()
            self._cv.notify_all()

    def pending(self, key: Any) -> bool:
        with self._cv:
            return key in self._due

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._closed and not self._due:
                    self._cv.wait()
                if self._closed:
                    return
                key, (due, fn) = min(self._due.items(), key=lambda kv: kv[1][0])
                left = due - time.monotonic()
                if left > 0:
                    self._cv.wait(left)
                    continue
                del self._due[key]
            try:
                fn()
            except Exception:  # a typing helper must survive anything
                import traceback

                traceback.print_exc()

    def close(self) -> None:
        with self._cv:
            self._closed = True
            self._due.clear()
            self._cv.notify_all()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(2)


class NumberField:
    """One number: a text box (what is typed is what is used), a slider to drag (linear, or
    log10 for ``log``), and a message line for refusals.

    ``value`` is the last good value in the quantity's own units; assigning to it from
    Python applies a good value (the callbacks run) and refuses a bad one like a typed one.
    ``report(field, text)`` is told every refusal (``text``) and every recovery (None)."""

    def __init__(
        self,
        gui,
        label: str,
        default: float,
        lo: float,
        hi: float,
        step: float,
        *,
        log: bool = False,
        digits: int = 3,
        unit: str = "",
        hint: str | None = None,
        slider: bool = True,
        marks: bool = True,
        deadlines: Deadlines | None = None,
        report: Callable[[NumberField, str | None], None] | None = None,
        lock: threading.RLock | None = None,
    ):
        if log and not 0 < lo < hi:
            raise ValueError(f"{label}: a log slider needs 0 < min < max (got {lo}, {hi})")
        self.label, self.default, self.min, self.max, self.step = label, float(default), float(lo), float(hi), step
        self.log, self.digits, self.unit = log, digits, unit
        self._value = float(default)
        self._deadlines, self._report = deadlines, report
        self._lock = lock or threading.RLock()
        self._quiet = False
        self._callbacks: list[Callable[[], None]] = []
        self.refused: str | None = None
        self.text = gui.add_text(label, fmt(default), hint=hint)
        self.slider = None
        if slider:
            a, b = (math.log10(lo), math.log10(hi)) if log else (lo, hi)
            ticks = (log_marks(lo, hi) if log else linear_marks(lo, hi)) if marks else None
            self.slider = gui.add_slider(
                " ", min=a, max=b, step=step, initial_value=self._to_slider(default), marks=ticks
            )
            self.slider.on_update(self._dragged)
        self.message = gui.add_html("", visible=False)
        self.text.on_update(self._typed)

    # ---------------------------------------------------------------- the value
    @property
    def value(self) -> float:
        return self._value

    @value.setter
    def value(self, v: float) -> None:
        self._commit(v, typed=None)

    def on_change(self, fn: Callable[[], None]) -> None:
        """Call ``fn()`` after the field took a new good value."""
        self._callbacks.append(fn)

    def set_quietly(self, v: float) -> None:
        """Show a value without running the callbacks (a reset, a link, the playing time)."""
        with self._lock:
            self._value = float(v)
            self._show(self._value, text=True)
            self._clear()

    def display(self, v: float) -> None:
        """Show a value that changes by itself (the playing time), unless a typed one waits."""
        if self._deadlines is not None and self._deadlines.pending(self):
            return
        self.set_quietly(v)

    def set_range(self, lo: float, hi: float) -> None:
        """A new allowed range (the time scrubber's end follows the run); linear fields without
        marks only (viser cannot change a slider's marks)."""
        if (lo, hi) == (self.min, self.max) or self.log:
            return
        self.min, self.max = float(lo), float(hi)
        if self.slider is not None:
            self._quiet = True
            try:
                self.slider.min, self.slider.max = self.min, self.max
            finally:
                self._quiet = False

    @property
    def unit_suffix(self) -> str:
        return f" {self.unit}" if self.unit else ""

    # ---------------------------------------------------------------- typing and dragging
    def _typed(self, event) -> None:
        if self._quiet:
            return
        if getattr(event, "client", None) is None or self._deadlines is None:
            self.apply_text()  # set from Python: at once
        else:
            self._deadlines.schedule(self, PAUSE_S, self.apply_text)

    def submit(self) -> None:
        """Enter was pressed in the field's form: apply what is typed (after its last keystroke)."""
        if self._deadlines is None:
            self.apply_text()
        elif self._deadlines.pending(self):
            self._deadlines.schedule(self, SUBMIT_DELAY_S, self.apply_text)

    def apply_text(self) -> None:
        """Read the box: a number within the range is applied; anything else is refused and
        left in the box as typed, with the reason beside it."""
        text = self.text.value
        try:
            v = parse_number(text)
        except ValueError as e:
            self._refuse(str(e))
            return
        self._commit(v, typed=text)

    def _dragged(self, event) -> None:
        if self._quiet or self.slider is None:
            return
        x = event.target.value if event is not None else self.slider.value
        try:
            x = float(x)
        except (TypeError, ValueError):
            x = math.nan
        lo, hi = float(self.slider.min), float(self.slider.max)
        tol = 1e-9 * (1 + abs(lo) + abs(hi))
        if not (math.isfinite(x) and lo - tol <= x <= hi + tol):
            why = "not a finite number" if not math.isfinite(x) else "outside the slider"
            with self._lock:
                self._show(self._value, text=False)
            self._refuse(f"slider value {x!r}: {why}; back to {fmt(self._value)}{self.unit_suffix}")
            return
        v = round_sig(10.0**x, self.digits) if self.log else float(fmt(round(x / self.step) * self.step))
        self._commit(min(max(v, self.min), self.max), typed=None, from_slider=True)

    # ---------------------------------------------------------------- inside
    def _commit(self, v, typed: str | None, from_slider: bool = False) -> None:
        try:
            x = float(v)
        except (TypeError, ValueError):
            self._refuse(f"{v!r} is not a number")
            return
        if not math.isfinite(x):
            self._refuse(f"{fmt(x)} is not a finite number")
            return
        if not self.min - 1e-12 * abs(self.min) <= x <= self.max + 1e-12 * abs(self.max):
            self._refuse(
                f"{typed if typed is not None else fmt(x)} is outside the allowed range "
                f"{fmt(self.min)} … {fmt(self.max)}{self.unit_suffix}"
            )
            return
        with self._lock:
            changed = x != self._value
            self._value = x
            self._show(x, text=typed is None, slider=not from_slider)
            self._clear()
        if changed:
            for fn in self._callbacks:
                fn()

    def _to_slider(self, v: float) -> float:
        if self.slider is not None:
            lo, hi = float(self.slider.min), float(self.slider.max)
        else:
            lo, hi = (math.log10(self.min), math.log10(self.max)) if self.log else (self.min, self.max)
        x = math.log10(v) if self.log else v
        return min(max(x, lo), hi)

    def _show(self, v: float, text: bool = True, slider: bool = True) -> None:
        self._quiet = True
        try:
            if text and self.text.value != fmt(v):
                self.text.value = fmt(v)
            if slider and self.slider is not None:
                self.slider.value = self._to_slider(v)
        finally:
            self._quiet = False

    def _refuse(self, why: str) -> None:
        keep = f"{fmt(self._value)}{self.unit_suffix}"
        self.refused = f"**input refused** — {self.label}: {why}; the run keeps {keep}"
        self.message.content = f'<div class="nmk-msg">⚠ {_html(why)}; the run keeps {_html(keep)}</div>'
        self.message.visible = True
        if self._report is not None:
            self._report(self, self.refused)

    def _clear(self) -> None:
        if self.refused is None:
            return
        self.refused = None
        self.message.visible = False
        if self._report is not None:
            self._report(self, None)


def _html(s: str) -> str:
    return s.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


class ExpressionField:
    """A typed expression (a plotted quantity): applied like a number box (Enter, or a pause
    in the typing), checked by ``check(text)`` (raises ValueError with the reason), refused
    beside the box when it cannot be read.  ``value`` is the last good text."""

    def __init__(
        self,
        gui,
        label: str,
        default: str,
        check: Callable[[str], object],
        *,
        hint: str | None = None,
        deadlines: Deadlines | None = None,
        report: Callable[[Any, str | None], None] | None = None,
    ):
        self.label, self.default, self.check = label, default, check
        self._value = default
        self._deadlines, self._report = deadlines, report
        self._callbacks: list[Callable[[], None]] = []
        self._quiet = False
        self.refused: str | None = None
        self.text = gui.add_text(label, default, hint=hint)
        self.message = gui.add_html("", visible=False)
        self.text.on_update(self._typed)

    @property
    def value(self) -> str:
        return self._value

    @value.setter
    def value(self, text: str) -> None:
        self._quiet = True
        try:
            self.text.value = text
        finally:
            self._quiet = False
        self.apply_text()

    def on_change(self, fn: Callable[[], None]) -> None:
        self._callbacks.append(fn)

    def set_quietly(self, text: str) -> None:
        self._value = text
        self._quiet = True
        try:
            self.text.value = text
        finally:
            self._quiet = False
        self._clear()

    def _typed(self, event) -> None:
        if self._quiet:
            return
        if getattr(event, "client", None) is None or self._deadlines is None:
            self.apply_text()
        else:
            self._deadlines.schedule(self, PAUSE_S, self.apply_text)

    def submit(self) -> None:
        if self._deadlines is None:
            self.apply_text()
        elif self._deadlines.pending(self):
            self._deadlines.schedule(self, SUBMIT_DELAY_S, self.apply_text)

    def apply_text(self) -> None:
        text = str(self.text.value).strip()
        try:
            self.check(text)
        except ValueError as e:
            self.refused = f"**input refused** — {self.label}: {e}; the plot keeps {self._value}"
            self.message.content = f'<div class="nmk-msg">⚠ {_html(str(e))}; the plot keeps {_html(self._value)}</div>'
            self.message.visible = True
            if self._report is not None:
                self._report(self, self.refused)
            return
        changed = text != self._value
        self._value = text
        self._clear()
        if changed:
            for fn in self._callbacks:
                fn()

    def _refuse(self, why: str) -> None:
        self.refused = f"**input refused** — {self.label}: {why}"
        self.message.content = f'<div class="nmk-msg">⚠ {_html(why)}</div>'
        self.message.visible = True
        if self._report is not None:
            self._report(self, self.refused)

    def _clear(self) -> None:
        if self.refused is None:
            return
        self.refused = None
        self.message.visible = False
        if self._report is not None:
            self._report(self, None)
