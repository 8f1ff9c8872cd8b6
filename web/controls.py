"""The control panel of one browser: GUI handles built from data, and their guard.

A system's simulation controls are described by :class:`Control` rows (what
:func:`web.generic.generic_controls` makes from a system's declaration); their ``field`` is
the run settings' own name (``dt``, ``gamma``, ``params.m``, ``initial.u1`` — the names of
the REST API and of page links).  :class:`ControlPanel` turns them into handles: a number
becomes a :class:`~web.numbers.NumberField` (a text box read exactly, a slider, a message
line), a choice a viser dropdown; it reads them back into the core's settings
(:func:`settings_from`) and collects refusals for the status line.

The run settings are :class:`~nmkane_core.schema.RunSettings`, as REST and the CLI take them:
a control's ``field`` names the setting it stands for, a number's range is cut to the range
the schema declares for that field (:func:`setting_control`, from :data:`SETTING_NUMBERS`),
and what no control sets (the tolerances among them) is left to the schema's defaults.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, replace

from nmkane_core.analysis.expressions import parse
from nmkane_core.integrate.methods import integrator_names
from nmkane_core.schema import LIMITS, RunSettings, field_range

from .numbers import Deadlines, ExpressionField, NumberField

INTEGRATORS = integrator_names()  # the core's, as the CLI offers them
DT_STEP = 0.05  # decades per slider step
TARGET_ROWS = 4000  # output rows kept per run for the animation (`every`)


def dt_of(log_dt: float) -> float:
    """The step size at a position of the log-scale slider, rounded to two significant digits."""
    return float(f"{10.0 ** float(log_dt):.2g}")


def every_of(dt: float, t_final: float) -> int:
    return max(1, round(t_final / dt / TARGET_ROWS))


@dataclass(frozen=True)
class Control:
    """One simulation control.

    ``attr`` names it uniquely on the page; ``field`` says where its value goes, in the run
    settings' names: ``"variant"`` (the system's model/formulation), ``"integrator"``,
    ``"projection"``, ``"gamma"``, ``"gamma1"``, ``"gamma2"``, ``"dt"``, ``"t_final"``,
    ``"initial.<name>"``, ``"params.<name>"``, or ``"option.<name>"`` (a display option of
    the view, e.g. compare).  ``kind`` is ``"number"``, ``"dropdown"`` or ``"checkbox"``.
    A number's ``min``, ``max`` and ``default`` are in its own units (``unit``), also on a
    ``log`` slider, whose ``step`` is in decades (then a dragged value keeps ``digits``
    significant digits)."""

    attr: str
    label: str
    field: str
    default: object
    kind: str = "number"
    min: float = 0.0
    max: float = 1.0
    step: float = 0.1
    log: bool = False
    unit: str = ""
    digits: int = 3
    options: tuple = ()
    hint: str | None = None


@dataclass(frozen=True)
class SettingNumber:
    """How the page shows a numeric run setting: its label, the slider's teaching range in the
    setting's unit (cut to the range the schema declares: :func:`setting_range`), step, scale."""

    label: str
    min: float
    max: float
    step: float
    unit: str = ""
    log: bool = False
    digits: int = 3


#: the run settings the page has numbers for, by RunSettings field (t_final's range is the system's)
SETTING_NUMBERS: dict[str, SettingNumber] = {
    "gamma": SettingNumber("Γ (nonholonomic)", -50.0, 10.0, 0.5, "1/s"),
    "gamma1": SettingNumber("Γ1 (holonomic)", -50.0, 10.0, 0.5, "1/s"),
    "gamma2": SettingNumber("Γ2 (holonomic)", -500.0, 50.0, 5.0, "1/s²"),
    "dt": SettingNumber("Δt", 1e-4, 0.2, DT_STEP, "s", log=True, digits=2),
    "t_final": SettingNumber("Final time", 1.0, 10.0, 0.05, "s"),
}
GAINS = ("gamma", "gamma1", "gamma2")


def setting_range(field: str, lo: float, hi: float) -> tuple[float, float]:
    """[lo, hi] cut to what :class:`RunSettings` allows for ``field`` (its declared range; a gain's
    is ±LIMITS["max_gain"]); an open bound is moved just inside."""
    if field in GAINS:
        limit = float(LIMITS["max_gain"])
        return max(lo, -limit), min(hi, limit)
    declared = field_range(field)
    if declared is None:
        return lo, hi
    low, low_in, high, high_in, _ = declared
    low = low if low_in else math.nextafter(low, math.inf)
    high = high if high_in else math.nextafter(high, -math.inf)
    return max(lo, low), min(hi, high)


def setting_control(attr: str, field: str, default: float, hint: str | None = None, **range_) -> Control:
    """The number for the run setting ``field`` (a key of :data:`SETTING_NUMBERS`; ``range_``:
    ``min``, ``max``, ``step`` of this system's), starting at ``default`` (the system's)."""
    n = SETTING_NUMBERS[field]
    lo, hi = setting_range(field, range_.get("min", n.min), range_.get("max", n.max))
    step = range_.get("step", n.step)
    label = f"{n.label} [{n.unit}]" if n.unit else n.label
    return Control(
        attr, label, field, default, min=lo, max=hi, step=step, log=n.log, unit=n.unit, digits=n.digits, hint=hint
    )


def dt_control(attr: str, default: float, hint: str | None = None) -> Control:
    """Δt, starting at ``default`` kept in the slider's range (a system's 1e-5 s starts at 1e-4)."""
    c = setting_control(attr, "dt", default, hint=hint)
    return replace(c, default=min(max(float(default), c.min), c.max))


#: s, the step size's slider (log scale): its teaching range within RunSettings' dt limits
DT_RANGE = setting_range("dt", SETTING_NUMBERS["dt"].min, SETTING_NUMBERS["dt"].max)


class ControlPanel:
    """The handles of the page's controls and the refusals they report.

    ``status()`` is called whenever the set of refusals changes (the status line shows
    them under the run's own status)."""

    def __init__(self, gui, status: Callable[[], None], lock: threading.RLock | None = None):
        self.gui = gui
        self._status = status
        self.lock = lock or threading.RLock()
        self.deadlines = Deadlines()
        self.refusals: dict[int, str] = {}  # id(field) -> its refusal
        self.notes: dict[str, list[str]] = {}  # refusals that belong to no box
        self.fields: list[NumberField | ExpressionField] = []
        self._quiet: set[int] = set()  # handles being written by the app itself

    # ---------------------------------------------------------------- building
    def add(self, c: Control):
        g = self.gui
        if c.kind == "dropdown":
            return g.add_dropdown(c.label, options=c.options, initial_value=c.default, hint=c.hint)
        if c.kind == "checkbox":
            return g.add_checkbox(c.label, initial_value=c.default, hint=c.hint)
        if c.kind == "text":  # a plotted quantity: an expression of the names in options
            names = c.options
            f = ExpressionField(
                g,
                c.label,
                str(c.default),
                lambda text: parse(text, names),
                hint=c.hint,
                deadlines=self.deadlines,
                report=self._report,
            )
            self.fields.append(f)
            return f
        assert isinstance(c.default, (int, float))
        return self.number(
            c.label, float(c.default), c.min, c.max, c.step, log=c.log, digits=c.digits, unit=c.unit, hint=c.hint
        )

    def form(self, label: str, **kw):
        """A folder whose boxes apply what is typed on Enter (viser's form)."""
        form = self.gui.add_form(label, **kw)
        form.on_submit(lambda _: self.submit())
        return form

    def number(self, label: str, default: float, lo: float, hi: float, step: float, **kw) -> NumberField:
        f = NumberField(
            self.gui, label, default, lo, hi, step, deadlines=self.deadlines, report=self._report, lock=self.lock, **kw
        )
        self.fields.append(f)
        return f

    # ---------------------------------------------------------------- refusals
    def refuse(self, field: NumberField | ExpressionField, text: str) -> None:
        """Show a refusal beside a field (a link's value, the core's check of a run)."""
        field._refuse(text)

    def _report(self, field, text: str | None) -> None:
        with self.lock:
            if text is None:
                self.refusals.pop(id(field), None)
            else:
                self.refusals[id(field)] = text
        self._status()

    def note(self, key: str, lines: list[str]) -> None:
        """Refusals that belong to no box (a link's unknown name, a choice it does not offer)."""
        with self.lock:
            if not lines and key not in self.notes:
                return
            self.notes[key] = [f"**input refused** — {line}" for line in lines]
            if not lines:
                del self.notes[key]
        self._status()

    def refusal_lines(self) -> list[str]:
        with self.lock:
            return [*self.refusals.values(), *(line for lines in self.notes.values() for line in lines)]

    def clear_refusals(self) -> None:
        for f in self.fields:
            f._clear()

    # ---------------------------------------------------------------- values
    def on_change(self, handle, fn: Callable[[], None]) -> None:
        """Call ``fn()`` when the handle takes a new good value."""
        if isinstance(handle, (NumberField, ExpressionField)):
            handle.on_change(fn)
        else:
            handle.on_update(lambda _: None if id(handle) in self._quiet else fn())

    def set_quietly(self, handle, value) -> None:
        """Set a value without running the actions of its callbacks."""
        if isinstance(handle, (NumberField, ExpressionField)):
            handle.set_quietly(value)
            return
        self._quiet.add(id(handle))
        try:
            handle.value = value
        finally:
            self._quiet.discard(id(handle))

    @staticmethod
    def value(handle):
        """A control's value (a number field's last good one)."""
        return handle.value

    def submit(self) -> None:
        """Enter in a form: apply every box whose typing has not been applied yet."""
        for f in self.fields:
            f.submit()

    def close(self) -> None:
        self.deadlines.close()


def settings_from(system, controls: dict, read: Callable) -> tuple[dict, dict]:
    """The core's settings (and the view's display options) from control values.

    ``controls`` maps :class:`Control` to its handle; ``read(handle)`` gives its value.  A
    control's field is a :class:`RunSettings` field (``variant`` is the system's variant field,
    ``model`` or ``formulation``; ``params.m``, ``initial.u1`` a key of one) or ``option.<name>``;
    a number is a float.  Every other setting is left to the schema's defaults (the tolerances,
    ``rtol`` and ``atol``, among them) but ``every``, which keeps about :data:`TARGET_ROWS` rows."""
    s: dict = {"system": system.name}
    options: dict = {}
    for c, h in controls.items():
        v = read(h)
        v = float(v) if c.kind == "number" else v
        field, _, key = c.field.partition(".")
        if field == "option":
            options[key] = v
            continue
        field = system.option if field == "variant" else field
        if field not in RunSettings.model_fields:
            raise ValueError(f"control {c.attr!r}: {c.field!r} is not a run setting (RunSettings has no {field!r})")
        if key:
            s.setdefault(field, {})[key] = v
        else:
            s[field] = v
    dt = float(s.get("dt", system.default_dt))
    t_final = float(s.get("t_final", system.default_t_final))
    if not (math.isfinite(dt) and dt > 0):
        dt = system.default_dt
    s.update(dt=dt, t_final=t_final, every=every_of(dt, t_final))
    return s, options
