"""One page for every registered system: controls, plots and scene made from the core System.

:class:`GenericView` is the only system view: everything it shows comes from data —
sliders for every parameter (over its declared range; on a log scale when it spans
decades), for the independent initial values (:attr:`nmkane_core.kernel.built.Built.independent`), for Γ only
when the system has nonholonomic constraints and Γ1, Γ2 only when it has holonomic ones,
Δt and the final time; choosers for the variant, integrator, projection, the compare runs
and the plotted coordinate; the energy drift, log10|violation| per constraint and the
chosen coordinate; and the scene the system declares (:mod:`web.declared`).  Where a
system declares a ``showcase`` (e.g. a paper's figure) the controls start there.

**Compare.**  The dropdown "Compare with (ghost)" runs other versions of the shown run
with the same settings: another variant (the other constraint model, the minimal
formulation), ``Γ = 0`` (the same run without stabilization, when the shown one has
some), or ``all`` of them.  Each compare run is drawn as a translucent ghost of the
system's moving visuals, in the colour of its dashed curves in the plots.
"""

from __future__ import annotations

import math

import numpy as np

from nmkane_core.analysis import expressions as ex
from nmkane_core.kernel.built import built
from nmkane_core.run.initial import default_state
from nmkane_core.run.plan import default_projection
from nmkane_core.run.registry import get_system
from nmkane_core.schema import PROJECTIONS, RunSettings

from . import curves as cv
from . import geometry as geo
from . import plots as pl
from .camera import CameraPlan, Viewport, follows, frame
from .controls import GAINS, INTEGRATORS, SETTING_NUMBERS, Control, dt_control, setting_control
from .declared import DeclaredScene
from .forces import TITLE as FORCES_TITLE
from .forces import ForceArrows, ForcePanel, force_curves

DECADES = 2.0  # a parameter range spanning this many decades gets a log slider
OFF, UNSTABILIZED, ALL = "off", "Γ = 0", "all"  # compare choices besides the variants


def _rgb(hex_color: str) -> tuple[int, int, int]:
    return int(hex_color[1:3], 16), int(hex_color[3:5], 16), int(hex_color[5:7], 16)


def _step(lo: float, hi: float, n: int = 200) -> float:
    return float(f"{(hi - lo) / n:.1g}") or 1e-3


def parameter_control(p, prefix: str) -> Control:
    """A number for a core Parameter, typed and shown in its unit: a linear slider over its
    range, or a log one when the range spans decades."""
    lo, hi, d = p.min, p.max, p.default
    if not math.isfinite(hi):
        hi = d + 4 * abs(d) if d else 1.0
    if not math.isfinite(lo):
        lo = d - 4 * abs(d) if d else -1.0
    label = f"{p.name} [{p.unit}]" if p.unit else p.name
    hint = p.description or None
    if d > 0 and (lo > 0 or not p.min_inclusive):
        low = lo if lo > 0 else min(d, hi) / 100.0  # an open range (0, max]: two decades below
        if math.log10(hi / low) >= DECADES:
            a, b = math.log10(low), math.log10(hi)
            return Control(
                f"{prefix}p_{p.name}",
                label,
                f"params.{p.name}",
                d,
                min=low,
                max=hi,
                step=_step(a, b),
                log=True,
                unit=p.unit,
                hint=hint,
            )
        lo = max(lo, low)
    return Control(
        f"{prefix}p_{p.name}", label, f"params.{p.name}", d, min=lo, max=hi, step=_step(lo, hi), unit=p.unit, hint=hint
    )


def initial_control(name: str, default: float, prefix: str, declared=None) -> Control:
    """An initial value's number: ``declared`` (min, max, label) from the System, else around the default."""
    span = max(3.0 * abs(default), 2.0)
    lo, hi, label = declared or (default - span, default + span, f"{name}(0)")
    return Control(f"{prefix}i_{name}", label, f"initial.{name}", default, min=lo, max=hi, step=_step(lo, hi))


#: the run settings the page offers as checkboxes: (field, label, hint, only for a model with constraints)
CHECKBOXES = (
    (
        "error_estimate",
        "Estimate the error",
        "run the same settings again at half the step (or a tenth of the tolerance) and show the difference: "
        "the estimated global error (a second run: about twice the time)",
        False,
    ),
    (
        "singular_projection",
        "Project near singular positions",
        "with Projection none, still project the steps that come near a singular position of the constraints, "
        "where the equations amplify any drift off the branch",
        True,
    ),
)


#: a folder's label longer than this wraps in viser's panel and covers the folder's first line
FOLDER_CHARS = 46


def folder_label(title: str, prefix: str = "Simulation: ") -> str:
    """The label of a system's folder: ``prefix`` + ``title``, within :data:`FOLDER_CHARS` (the
    scene menu shows the whole title): a long title loses its parenthesis, then its last words."""
    label = prefix + title
    if len(label) > FOLDER_CHARS and title.endswith(")") and " (" in title:
        label = prefix + title[: title.rindex(" (")]
    if len(label) <= FOLDER_CHARS:
        return label
    words = label[len(prefix) :].split(" ")
    while len(words) > 1 and len(prefix + " ".join(words)) + 1 > FOLDER_CHARS:
        words.pop()
    return (prefix + " ".join(words).rstrip(",:;"))[: FOLDER_CHARS - 1] + "…"


def compare_choices(core) -> tuple[str, ...]:
    """The compare dropdown of a system: off, each variant, Γ = 0 (when it has constraints
    to stabilize), and all of them (when that is more than one run)."""
    info = built(core).info(core.default_variant)
    runs = [*core.variants] if len(core.variants) > 1 else []
    if info.nonholonomic or info.holonomic:
        runs.append(UNSTABILIZED)
    return (OFF, *runs, *((ALL,) if len(runs) > 2 or (len(runs) == 2 and len(core.variants) == 1) else ()))


def generic_controls(core, prefix: str) -> tuple[Control, ...]:
    """The simulation controls of any system, from its declaration and its model's info:
    the choosers, the Baumgarte gains its constraints need, the time step and final time,
    the independent initial values and the plotted coordinate."""
    show = dict(getattr(core, "showcase", {}))
    return (
        *_choosers(core, prefix, show),
        *_gains(core, prefix, show),
        *_times(core, prefix, show),
        *_initials(core, prefix),
        *_plot_controls(core, prefix),
    )


def _plot_controls(core, prefix: str) -> list[Control]:
    """The plotted quantity: an expression of the run's quantities, against time or another one."""
    b = built(core)
    info = b.info(core.default_variant)
    names = ex.names_of((*b.state_names, *info.outputs), info.viol_names, info.has_energy)  # the model's outputs too
    hint = f"an expression of {', '.join(names)}; functions such as sin, sqrt; ^ for powers"
    return [
        Control(f"{prefix}plot", "Plot y =", "option.plot", b.state_names[0], kind="text", options=names, hint=hint),
        Control(f"{prefix}plot_x", "against x =", "option.plot_x", "t", kind="text", options=names, hint=hint),
    ]


def _choosers(core, prefix: str, show: dict) -> list[Control]:
    """Variant (when there are several), compare, integrator and projection."""
    out = []
    if len(core.variants) > 1:
        variant = show.get("variant", core.default_variant)
        out.append(
            Control(
                f"{prefix}variant",
                core.option.capitalize(),
                "variant",
                variant,
                kind="dropdown",
                options=tuple(core.variants),
            )
        )
    choices = compare_choices(core)
    if len(choices) > 1:
        first = show.get("compare", OFF)
        out.append(
            Control(
                f"{prefix}compare",
                "Compare with (ghost)",
                "option.compare",
                first if first in choices else OFF,
                kind="dropdown",
                options=choices,
                hint="other runs with the same settings, drawn translucent and dashed in the plots",
            )
        )
    integ = show.get("integrator", core.default_integrator)
    integ = integ if integ in INTEGRATORS else core.default_integrator
    out.append(Control(f"{prefix}integrator", "Integrator", "integrator", integ, kind="dropdown", options=INTEGRATORS))
    proj = show.get("projection", default_projection(core, core.default_variant))  # the system's own
    proj = proj if proj in PROJECTIONS else "none"
    out.append(Control(f"{prefix}projection", "Projection", "projection", proj, kind="dropdown", options=PROJECTIONS))
    constrained = built(core).info(core.default_variant).m > 0
    for field, label, hint, needs_constraints in CHECKBOXES:
        if constrained or not needs_constraints:
            default = bool(show.get(field, RunSettings.model_fields[field].default))  # the schema's default
            out.append(Control(f"{prefix}{field}", label, field, default, kind="checkbox", hint=hint))
    return out


def _gains(core, prefix: str, show: dict) -> list[Control]:
    """Γ when the system has nonholonomic constraints; Γ1, Γ2 when it has holonomic ones."""
    info = built(core).info(core.default_variant)
    shown = (("gamma",) if info.nonholonomic else ()) + (("gamma1", "gamma2") if info.holonomic else ())
    return [_gain_control(prefix, g, float(show.get(g, getattr(core, f"default_{g}")))) for g in shown]


def _gain_control(prefix: str, gain: str, default: float) -> Control:
    """A gain's number; its slider widened to take the system's own default (a stiff system's
    Γ2 = −1e6 lay outside −500…50: the page started there, and typing it back was refused)."""
    n = SETTING_NUMBERS[gain]
    lo, hi = min(n.min, 1.25 * default), max(n.max, 1.25 * default)
    if (lo, hi) == (n.min, n.max):
        return setting_control(f"{prefix}{gain}", gain, default)
    return setting_control(f"{prefix}{gain}", gain, default, min=lo, max=hi, step=_step(lo, hi))


def _times(core, prefix: str, show: dict) -> list[Control]:
    """The step size (a log slider) and the final time."""
    tf = float(show.get("t_final", core.default_t_final))
    hi = max(5 * tf, 10.0)
    return [
        dt_control(f"{prefix}dt", float(show.get("dt", core.default_dt))),  # kept in the slider's range
        setting_control(f"{prefix}t_final", "t_final", tf, min=min(1.0, tf), max=hi, step=_step(0, hi)),
    ]


def _initials(core, prefix: str) -> list[Control]:
    """The initial values the system declares sliders for (default: its independent ones)."""
    shown = getattr(core, "initial_controls", None) or dict.fromkeys(built(core).independent)
    state = default_state(core)
    return [initial_control(name, float(state.get(name, 0.0)), prefix, declared) for name, declared in shown.items()]


class GenericView:
    """One system on the page, from its core declaration (one instance per system and browser).

    ``kind`` (the system's name) keys its plots and folder on the page; ``runs`` turns the
    controls' settings into the runs of one request (the shown one first, then the compare
    runs), ``curves`` into plot data, and the scene (:class:`~web.declared.DeclaredScene`,
    plus one ghost per compare run) is shaped once per trajectory and posed per frame."""

    params_folder = "Physical parameters"
    reset_label = "Reset to the defaults"

    def __init__(self, scene, name: str):
        self.scene = scene
        self.system = name
        core = get_system(name)
        self.kind = name
        self.title = core.title or name
        self.folder = folder_label(self.title)
        prefix = f"g_{''.join(c if c.isalnum() else '_' for c in name)}_"
        self.params_attr = f"{prefix}params"
        self.speed = float(getattr(core, "showcase", {}).get("speed", 1.0))
        self.controls = generic_controls(core, prefix)
        self._param_controls = tuple(parameter_control(p, prefix) for p in core.parameters)
        self.plots: tuple[tuple[str, str], ...] = (
            ("energy", "Energy drift ΔE(t)"),
            ("violation", "log₁₀ |constraint violation|"),
            ("coord", "Plotted quantity"),
        )
        self.declared = DeclaredScene(scene, core)
        self.forces = ForceArrows(scene, core, self.declared.prefix)  # the declared forces' arrows
        self.force_panel: ForcePanel | None = None  # its checkbox and readout (the session adds them to the folder)
        if self.forces.declared:
            self.plots = (*self.plots[:2], ("forces", FORCES_TITLE), *self.plots[2:])
        self.ghosts: list[DeclaredScene] = []  # one per compare run, made on first use
        self.root = self.declared.root
        self.plot_y, self.plot_x = built(core).state_names[0], "t"  # the typed plotted quantity
        self.k = 0
        self.fit_pending = True
        self.plan: CameraPlan | None = None  # how the installed run is looked at

    @property
    def core(self):
        return get_system(self.system)

    @property
    def param_controls(self) -> tuple[Control, ...]:
        return self._param_controls

    def matrices_variant(self, settings: dict) -> str:
        return settings.get(self.core.option, self.core.default_variant)

    def matrices_variants(self) -> tuple[str, ...]:
        core = self.core
        return (core.default_variant, *(v for v in core.variants if v != core.default_variant))

    # ---------------------------------------------------------------- runs and plots
    def runs(self, settings: dict, options: dict) -> dict[str, dict]:
        """label -> the core's settings of each run of one request: the shown run, then the
        compare runs (same settings; another variant, or Γ = 0)."""
        core = self.core
        self.plot_y = options.get("plot", self.plot_y)
        self.plot_x = options.get("plot_x", self.plot_x)
        main = settings.get(core.option, core.default_variant)
        out = {main: settings}
        compare = options.get("compare", OFF)
        picks = [*core.variants, UNSTABILIZED] if compare == ALL else [compare]
        shown = built(core).info(main)
        for pick in picks:
            if pick == UNSTABILIZED:  # the shown run without its gains (none: it is the shown run again)
                s = {**settings, **{g: 0.0 for g in GAINS if g in settings}}
                if s != settings and (shown.nonholonomic or shown.holonomic):
                    out[f"{main}, Γ = 0"] = s
            elif pick in core.variants and pick != main:
                info = built(core).info(pick)
                drop = {"gamma"} if not info.nonholonomic else set()
                drop |= {"gamma1", "gamma2"} if not info.holonomic else set()
                out[pick] = {k: v for k, v in {**settings, core.option: pick}.items() if k not in drop}
        return out

    def curves(self, runs: dict) -> dict:
        """Plot data of one request's runs (:mod:`web.curves`): energy drift, violations, and
        the typed quantity against time or against another quantity (key ``phase``)."""
        out: dict = {"energy": cv.energy(runs), "violation": cv.violation(runs)}
        if self.forces.declared:
            out["forces"] = self._force_curves(runs)
        try:
            q = cv.quantity(runs, self.plot_y, self.plot_x)
        except ex.ExpressionError as e:  # a name the runs lack (the box checked the system's names)
            main = next(iter(runs.values()))
            q = pl.curves(main.t, [np.zeros(len(main.t))], [f"({e})"], y_label=self.plot_y)
        out["phase" if isinstance(q, cv.Phase) else "coord"] = q
        return out

    def _force_curves(self, runs: dict) -> pl.Curves:
        """|F| of each declared force (a flat line saying so when the runs' models declare none)."""
        main = next(iter(runs.values()))
        out = force_curves(self.core, runs, main.t, lambda r, v: cv.on_main(main, r, v))
        return out or pl.curves(main.t, [np.zeros(len(main.t))], ["(no forces declared for this model)"])

    def legend(self, traj) -> str:
        """Which colour (and line style) is which run, in the panel (the scene names the ghosts too)."""
        labels = list(traj.runs)
        if len(labels) < 2:
            return ""
        parts = [f"**{pl.RUN_COLOR_NAMES[0]}**, solid: {labels[0]} (shown)"]
        for j, lab in enumerate(labels[1:], start=1):
            color = pl.RUN_COLOR_NAMES[j % len(pl.RUN_COLOR_NAMES)]
            parts.append(f"**{color}**, {pl.DASH_NAMES[(j - 1) % len(pl.DASH_NAMES)]}: {lab} (ghost)")
        return "Runs — " + " · ".join(parts)

    def series_style(self, key: str, i: int, traj) -> dict:
        styles = traj.plots[key].styles
        return styles[i] if i < len(styles) else {"stroke": pl.COLORS[i % len(pl.COLORS)]}

    # ---------------------------------------------------------------- scene
    def install(self, traj) -> None:
        runs, labels = list(traj.runs.values()), list(traj.runs)
        self.declared.install(runs[0], traj.params)
        self.forces.install(runs[0], traj.params, self.declared.extent)
        for j, run in enumerate(runs[1:], start=1):
            if len(self.ghosts) < j:
                color = _rgb(pl.RUN_COLORS[j % len(pl.RUN_COLORS)])
                self.ghosts.append(DeclaredScene(self.scene, self.core, ghost=color, index=j))
            self.ghosts[j - 1].install(run, traj.params)
            name = f"{pl.RUN_COLOR_NAMES[j % len(pl.RUN_COLOR_NAMES)]} ghost: {labels[j]}"
            self.ghosts[j - 1].tag(name, row=j, spacing=0.15 * self.declared.extent)
        for j, g in enumerate(self.ghosts, start=1):
            g.root.visible = j < len(runs)
        self.plan = self.camera_plan()

    def pose(self, traj, t_now: float) -> dict:
        labels = list(traj.runs)
        self.k = geo.index_at(traj.runs[labels[0]].t, t_now)
        self.declared.pose(self.k)
        self.forces.pose(self.k)
        for g, lab in zip(self.ghosts, labels[1:], strict=False):
            g.pose(geo.index_at(traj.runs[lab].t, t_now))
        return traj.row(labels[0], t_now)

    def label_points(self) -> list:
        """The labels shown at the shown row with their world points: the parts' names first
        (they keep their places), then the forces', then the ghosts' names."""
        ghosts = [p for g in self.ghosts if g.root.visible for p in g.label_points()]
        return [*self.declared.label_points(self.k), *self.forces.label_points(self.k), *ghosts]

    def readouts(self, traj, t_now: float) -> None:
        """Slow-rate labels: the forces' magnitudes at their arrows and the readout in the panel."""
        self.forces.readout(self.k)
        if self.force_panel is not None:
            self.force_panel.show(traj.main, t_now)

    def _centre(self) -> np.ndarray:
        """The point a following camera follows at the shown row (the mean of the frame origins,
        or the first moving part)."""
        return self.declared.centre_at(self.k)

    def _side(self, direction=None):
        """The side a camera looks from: ``direction`` if given, else the system's declared one."""
        if direction is not None:
            return direction
        d = self.declared
        return None if d.compiled is None else d.compiled.view

    def camera_plan(self, viewport: Viewport | None = None) -> CameraPlan | None:
        """How to look at the installed run (:mod:`web.camera`): every path travelled (the
        export), the parts' whole motion (a fixed first view), and the envelope of the parts
        around the point followed (a following first view); it follows when the fixed view
        would show the mechanism much smaller.  Seen from the side the system declares
        (``Visuals.view``), if it does."""
        d = self.declared
        whole = d.bounds()
        if whole is None:
            return None
        side = self._side()
        motion = frame(d.parts_motion() or whole, side, viewport)
        envelope = d.parts_envelope()
        if envelope is None:  # nothing to frame but the paths: around the first row
            envelope = (whole[0] - d.centre_at(0), whole[1] - d.centre_at(0))
        look, pos = frame(envelope, side, viewport)  # around the point followed (at the origin)
        return CameraPlan(
            whole=frame(whole, side, viewport),
            motion=motion,
            offset=pos - look,
            shift=look,
            follows=follows(motion, (look, pos)),
        )

    def fit_now(self, viewport: Viewport | None = None, direction=None) -> tuple[np.ndarray, np.ndarray] | None:
        """(look_at, position) framing the mechanism as it is at the shown row (*Fit view*),
        from ``direction`` (default: the declared side)."""
        d = self.declared
        box = d.mechanism_at(self.k) or d.bounds()
        if box is None:
            return None
        return frame(box, self._side(direction), viewport)

    def follow_target(self) -> np.ndarray:
        """Where a following camera looks at the shown row (it translates with the bodies)."""
        plan = self.plan
        return self._centre() + (plan.shift if plan is not None else 0.0)


def scene_choices() -> dict[str, str]:
    """The scene dropdown: title -> system name for every registered system (built-in,
    catalogue, plugged in), in the registry's order."""
    from nmkane_core.run.registry import system_names

    out: dict[str, str] = {}
    for name in system_names():
        try:
            title = get_system(name).title or name
        except Exception:  # a broken plug-in: listed by name, reported when chosen
            title = name
        out[title if title not in out else f"{title} ({name})"] = name
    return out


def warm_systems(skip=(), stopped=lambda: False) -> list[tuple[str, str]]:
    """Load every registered system's kernels and loops (a short run of each variant) and
    compile its visuals, so that choosing it (or comparing) later is quick; returns
    (system, default variant) of each, for the matrices.  Ends early once ``stopped()``."""
    import contextlib

    from nmkane_core.kernel.visuals import compile_visuals
    from nmkane_core.run.registry import system_names
    from nmkane_core.run.simulate import simulate

    out = []
    for name in system_names():
        if stopped():
            break
        if name in skip:
            continue
        with contextlib.suppress(Exception):
            core = get_system(name)
            simulate({"system": name, "t_final": 0.05}, progress=False)
            compile_visuals(core)
            for v in core.variants:
                if v != core.default_variant:
                    simulate({"system": name, core.option: v, "t_final": 0.05}, progress=False)
            out.append((name, core.default_variant))
    return out
