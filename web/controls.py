"""The control panel of one browser: GUI handles built from data, and their guard.

A system's simulation controls are described by :class:`Control` rows (what
:func:`web.generic.generic_controls` makes from a system's declaration);
:class:`ControlPanel` turns them into viser handles, reads them back into the core's
settings (:func:`settings_from`), resets them to their defaults, and guards every
slider: a value that is not finite or lies outside the slider's range (a websocket
message can carry either) is refused with a message in the status panel and the slider
goes back to its last good value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

INTEGRATORS = ("kutta-merson", "rk4", "kutta-merson-adaptive", "rk45", "dop853", "radau")
DT_MARKS = ((-4.0, "1e-4"), (-3.0, "1e-3"), (-2.0, "0.01"), (-1.0, "0.1"))
LOG_DT_RANGE = (-4.0, math.log10(0.2), 0.05)
TARGET_ROWS = 4000  # output rows kept per run for the animation (`every`)


def dt_of(log_dt: float) -> float:
    """The step size of the log-scale slider, rounded to two significant digits."""
    return float(f"{10.0 ** float(log_dt):.2g}")


def every_of(dt: float, t_final: float) -> int:
    return max(1, round(t_final / dt / TARGET_ROWS))


@dataclass(frozen=True)
class Control:
    """One simulation control.

    ``attr`` names the handle on the session (``app.gamma``); ``field`` says where its value
    goes: ``"variant"`` (the system's model/formulation), ``"integrator"``, ``"gamma"``,
    ``"gamma1"``, ``"gamma2"``, ``"log_dt"``, ``"t_final"``, ``"initial.<name>"``,
    ``"params.<name>"``, ``"logparams.<name>"`` (a log10 slider), ``"projection"``, or
    ``"option.<name>"`` (a display option of the view, e.g. compare).
    ``kind`` is ``"slider"``, ``"dropdown"`` or ``"checkbox"``."""

    attr: str
    label: str
    field: str
    default: object
    kind: str = "slider"
    min: float = 0.0
    max: float = 1.0
    step: float = 0.1
    options: tuple = ()
    marks: tuple | None = None
    hint: str | None = None


def log_dt_control(attr: str, label: str, default: float, hint: str | None = None) -> Control:
    lo, hi, step = LOG_DT_RANGE
    return Control(attr, label, "log_dt", default, min=lo, max=hi, step=step, marks=DT_MARKS, hint=hint)


class ControlPanel:
    """The handles of one view's controls, their defaults, and the guard of every slider.

    ``refuse(text)`` shows a refusal in the status panel; ``changed()`` is called after a
    simulation control took a good value."""

    def __init__(self, gui, refuse: Callable[[str], None]):
        self.gui = gui
        self._refuse = refuse
        self._good: dict[int, float] = {}  # id(handle) -> last good value
        self._restoring: set[int] = set()  # handles being written by the app itself

    # ---------------------------------------------------------------- building
    def add(self, c: Control):
        g = self.gui
        if c.kind == "dropdown":
            return g.add_dropdown(c.label, options=c.options, initial_value=c.default)
        if c.kind == "checkbox":
            return g.add_checkbox(c.label, initial_value=c.default)
        kw: dict[str, object] = {"marks": c.marks} if c.marks else {}
        if c.hint:
            kw["hint"] = c.hint
        return self.slider(c.label, min=c.min, max=c.max, step=c.step, initial_value=c.default, **kw)

    def slider(self, label: str, **kw):
        h = self.gui.add_slider(label, **kw)
        self._good[id(h)] = float(h.value)
        return h

    # ---------------------------------------------------------------- the guard
    def on_change(self, handle, fn: Callable[[], None]) -> None:
        """Call ``fn()`` when the handle takes a new good value (sliders are guarded)."""
        if id(handle) not in self._good:
            handle.on_update(lambda _: None if id(handle) in self._restoring else fn())
            return

        def update(_event) -> None:
            if id(handle) in self._restoring:
                return
            if self.accept(handle):
                fn()

        handle.on_update(update)

    def accept(self, handle) -> bool:
        """Keep a good slider value; refuse a bad one and put the last good value back."""
        v = handle.value
        try:
            x = float(v)
        except (TypeError, ValueError):
            x = math.nan
        lo, hi = float(handle.min), float(handle.max)
        if math.isfinite(x) and lo - 1e-9 * (1 + abs(lo)) <= x <= hi + 1e-9 * (1 + abs(hi)):
            self._good[id(handle)] = x
            return True
        good = self._good[id(handle)]
        why = "not a finite number" if not math.isfinite(x) else "outside the slider's range"
        self._refuse(
            f"**input refused** — {handle.label.strip()} = {v!r}: {why} "
            f"(allowed: {lo:g} … {hi:g}); back to {good:g}  \nthe previous motion keeps playing"
        )
        self.set_quietly(handle, good)
        return False

    def set_quietly(self, handle, value) -> None:
        """Set a value without running the actions of its callbacks."""
        self._restoring.add(id(handle))
        try:
            handle.value = value
        finally:
            self._restoring.discard(id(handle))
        if id(handle) in self._good:
            self._good[id(handle)] = float(handle.value)

    def value(self, handle):
        """A control's value; a slider's last good one (a refused value may still sit in the
        handle while its callback is on the way)."""
        return self._good.get(id(handle), handle.value)


def settings_from(system, controls: dict, read: Callable) -> tuple[dict, dict]:
    """The core's settings (and the view's display options) from control values.

    ``controls`` maps :class:`Control` to its handle; ``read(handle)`` gives its value."""
    s: dict = {"system": system.name}
    options: dict = {}
    dt = t_final = None
    for c, h in controls.items():
        v = read(h)
        kind, _, name = c.field.partition(".")
        if kind == "variant":
            s[system.option] = v
        elif kind in ("integrator", "projection"):
            s[kind] = v
        elif kind in ("gamma", "gamma1", "gamma2"):
            s[kind] = float(v)
        elif kind == "log_dt":
            dt = dt_of(v)
        elif kind == "t_final":
            t_final = float(v)
        elif kind in ("initial", "params"):
            s.setdefault(kind, {})[name] = float(v)
        elif kind == "logparams":  # a log-scale slider: its value is log10
            s.setdefault("params", {})[name] = float(f"{10.0 ** float(v):.6g}")
        elif kind == "option":
            options[name] = v
    dt = system.default_dt if dt is None else dt
    t_final = system.default_t_final if t_final is None else t_final
    s.update(dt=dt, t_final=t_final, every=every_of(dt, t_final), rtol=1e-9, atol=1e-10)
    return s, options
