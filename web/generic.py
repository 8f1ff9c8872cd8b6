"""One page for any registered system: controls, plots and scene made from the core System.

:class:`GenericView` implements :class:`~web.systems.SystemView` from data only: sliders
for every parameter (over its declared range; on a log scale when it spans decades), for
the independent initial values (:attr:`System.independent`), for Γ only when the system
has nonholonomic constraints and Γ1, Γ2 only when it has holonomic ones, Δt and the final
time; choosers for the variant, integrator, projection and the plotted coordinate; the
energy drift, log10|violation| per constraint and the chosen coordinate; and the scene
the system declares (:mod:`web.declared`).
"""

from __future__ import annotations

import math
from typing import ClassVar

import numpy as np

from nmkane_core.projection import PRESETS
from nmkane_core.registry import get_system

from . import geometry as geo
from . import plots as pl
from .controls import INTEGRATORS, Control, log_dt_control
from .declared import DeclaredScene, fit_camera
from .systems import COLORS, SystemView

DECADES = 2.0  # a parameter range spanning this many decades gets a log slider


def _step(lo: float, hi: float, n: int = 200) -> float:
    return float(f"{(hi - lo) / n:.1g}") or 1e-3


def parameter_control(p, prefix: str) -> Control:
    """A slider for a core Parameter: linear over its range, or log10 when it spans decades."""
    lo, hi, d = p.min, p.max, p.default
    if not math.isfinite(hi):
        hi = d + 4 * abs(d) if d else 1.0
    if not math.isfinite(lo):
        lo = d - 4 * abs(d) if d else -1.0
    label = f"{p.name} [{p.unit}]" if p.unit else p.name
    if d > 0 and (lo > 0 or not p.min_inclusive):
        low = lo if lo > 0 else min(d, hi) / 100.0  # an open range (0, max]: two decades below
        if math.log10(hi / low) >= DECADES:
            a, b = math.log10(low), math.log10(hi)
            return Control(
                f"{prefix}p_{p.name}",
                f"log₁₀ {label}",
                f"logparams.{p.name}",
                round(math.log10(d), 6),
                min=a,
                max=b,
                step=_step(a, b),
                hint=f"{p.description} (log scale: {low:g} … {hi:g})",
            )
        lo = max(lo, low)
    return Control(
        f"{prefix}p_{p.name}",
        label,
        f"params.{p.name}",
        d,
        min=lo,
        max=hi,
        step=_step(lo, hi),
        hint=p.description or None,
    )


def initial_control(name: str, default: float, prefix: str, declared=None) -> Control:
    """An initial value's slider: ``declared`` (min, max, label) from the System, else around the default."""
    span = max(3.0 * abs(default), 2.0)
    lo, hi, label = declared or (default - span, default + span, f"{name}(0)")
    return Control(f"{prefix}i_{name}", label, f"initial.{name}", default, min=lo, max=hi, step=_step(lo, hi))


def generic_controls(core, prefix: str) -> tuple[Control, ...]:
    """The simulation controls of any system, from its declaration and its model's info."""
    info = core.info(core.default_variant)
    out = []
    if len(core.variants) > 1:
        out.append(
            Control(
                f"{prefix}variant",
                core.option.capitalize(),
                "variant",
                core.default_variant,
                kind="dropdown",
                options=tuple(core.variants),
            )
        )
    integ = core.default_integrator if core.default_integrator in INTEGRATORS else INTEGRATORS[0]
    out.append(Control(f"{prefix}integrator", "Integrator", "integrator", integ, kind="dropdown", options=INTEGRATORS))
    out.append(
        Control(f"{prefix}projection", "Projection", "projection", "none", kind="dropdown", options=tuple(PRESETS))
    )
    if info.nonholonomic:
        out.append(
            Control(f"{prefix}gamma", "Γ (nonholonomic)", "gamma", core.default_gamma, min=-50.0, max=10.0, step=0.5)
        )
    if info.holonomic:
        out.append(
            Control(
                f"{prefix}gamma1", "Γ1 (holonomic) [1/s]", "gamma1", core.default_gamma1, min=-50.0, max=10.0, step=0.5
            )
        )
        out.append(
            Control(
                f"{prefix}gamma2",
                "Γ2 (holonomic) [1/s²]",
                "gamma2",
                core.default_gamma2,
                min=-500.0,
                max=50.0,
                step=5.0,
            )
        )
    log_dt = min(max(math.log10(core.default_dt), -4.0), math.log10(0.2))
    out.append(log_dt_control(f"{prefix}log_dt", "log₁₀ Δt [s]", round(log_dt, 2)))
    tf = core.default_t_final
    out.append(
        Control(
            f"{prefix}t_final",
            "Final time [s]",
            "t_final",
            tf,
            min=min(1.0, tf),
            max=max(5 * tf, 10.0),
            step=_step(0, max(5 * tf, 10.0)),
        )
    )
    shown = getattr(core, "initial_controls", None) or dict.fromkeys(core.independent)
    for name, declared in shown.items():
        out.append(initial_control(name, float(core.default_initial.get(name, 0.0)), prefix, declared))
    names = core.state_names
    out.append(Control(f"{prefix}plot", "Plotted coordinate", "option.plot", names[0], kind="dropdown", options=names))
    return tuple(out)


class GenericView(SystemView):
    """Any system on the page, from its core declaration (one instance per system and browser)."""

    follows = True
    camera_views: ClassVar[dict] = {"system": None}
    reset_label = "Reset to the system's defaults"
    speed = 1.0

    def __init__(self, scene, name: str):
        self.system = name
        core = get_system(name)
        self.kind = f"gen:{name}"
        self.title = core.title or name
        self.folder = f"Simulation: {self.title}"
        prefix = f"g_{''.join(c if c.isalnum() else '_' for c in name)}_"
        self.params_attr = f"{prefix}params"
        self.controls = generic_controls(core, prefix)
        self._param_controls = tuple(parameter_control(p, prefix) for p in core.parameters)
        self.plots = (
            ("energy", "Energy drift ΔE(t)"),
            ("violation", "log₁₀ |constraint violation|"),
            ("coord", "Plotted coordinate"),
        )
        super().__init__(scene)
        self.declared = DeclaredScene(scene, core)
        self.root = self.declared.root
        self.plot_name = core.state_names[0]
        self.k = 0
        self.fit_pending = True
        self.fixed_target = None  # the whole motion fits in view: the camera stays put
        self.offset = None

    @property
    def param_controls(self) -> tuple[Control, ...]:
        return self._param_controls

    def matrices_variants(self) -> tuple[str, ...]:  # instance-level: the system is per view
        core = self.core
        return (core.default_variant, *(v for v in core.variants if v != core.default_variant))

    # ---------------------------------------------------------------- runs and plots
    def runs(self, settings: dict, options: dict) -> dict[str, dict]:
        self.plot_name = options.get("plot", self.plot_name)
        return {settings.get(self.core.option, self.core.default_variant): settings}

    def curves(self, runs: dict) -> dict:
        run = next(iter(runs.values()))
        t = run.t
        e = np.zeros(len(t)) if run.energy is None else np.asarray(run.energy, float)
        dE = e - e[0] if len(e) else e
        factor, unit = pl.readable([dE], "J")
        names = list(run.violation) or ["(no constraints)"]
        ys = [pl.log10_abs(run.violation[c]) for c in run.violation] or [np.full(len(t), math.log10(pl.LOG_FLOOR))]
        name = self.plot_name if self.plot_name in run.state else next(iter(run.state))
        return {
            "energy": pl.curves(t, [dE / factor], [f"ΔE [{unit}]"]),
            "violation": pl.curves(t, ys, names),
            "coord": pl.curves(t, [run.state[name]], [name]),
        }

    def series_style(self, key: str, i: int, traj) -> dict:
        return {"stroke": COLORS[i % len(COLORS)]}

    # ---------------------------------------------------------------- scene
    def install(self, traj) -> None:
        self.declared.install(traj.main, traj.params)
        self._plan_camera(traj)

    def pose(self, traj, t_now: float) -> dict:
        label = next(iter(traj.runs))
        self.k = geo.index_at(traj.runs[label].t, t_now)
        self.declared.pose(self.k)
        return traj.row(label, t_now)

    def rest_row(self) -> dict:
        return {}

    def _centre(self) -> np.ndarray:
        """The mean of the frame origins (or the point) at the shown row."""
        d = self.declared
        if d.frame_poses:
            return np.mean([pos[min(self.k, len(pos) - 1)] for pos, _ in d.frame_poses.values()], axis=0)
        if d.points and d.compiled is None:
            return d.points[0][min(self.k, len(d.points[0]) - 1)]
        return np.zeros(3)

    def _plan_camera(self, traj) -> None:
        """Fixed on the whole motion when it is not much larger than the system; else follow it."""
        b = self.declared.bounds()
        if b is None:
            return
        lo, hi = b
        whole = float(np.linalg.norm(hi - lo)) / 2
        size = self._size()
        if whole <= 3.0 * size + 1.0:
            self.fixed_target, self.offset = fit_camera(b)
            self.offset = self.offset - self.fixed_target
        else:
            c = self._centre()
            look, pos = fit_camera((c - 1.2 * size, c + 1.2 * size))
            self.fixed_target, self.offset = None, pos - look

    def _size(self) -> float:
        """A length of the system itself: its largest shape (1 m if none)."""
        cv = self.declared.compiled
        if cv is None or self.declared.sizes_for is None:
            return 0.5
        sizes = cv.sizes(dict(self.declared.sizes_for))
        big = [
            abs(float(v))
            for s in cv.shapes
            if s["kind"] in ("box", "cylinder", "sphere")
            for v in sizes[s["size"][0] : s["size"][0] + s["size"][1]]
        ]
        return max(big, default=0.5)

    def camera_target(self, row: dict | None, view: str) -> np.ndarray:
        return self.fixed_target if self.fixed_target is not None else self._centre()

    def camera_offset(self, row: dict | None, view: str) -> np.ndarray:
        return self.offset if self.offset is not None else np.array([2.0, -3.0, 2.0])


def warm_systems(skip=()) -> list[tuple[str, str]]:
    """Load every registered system's kernel and loops (a short run) and compile its visuals, so
    that choosing it later is quick; returns (system, default variant) of each, for the matrices."""
    import contextlib

    from nmkane_core.registry import system_names
    from nmkane_core.simulate import simulate
    from nmkane_core.visuals import compile_visuals

    out = []
    for name in system_names():
        if name in skip:
            continue
        with contextlib.suppress(Exception):
            core = get_system(name)
            simulate({"system": name, "t_final": 0.05}, progress=False)
            compile_visuals(core)
            out.append((name, core.default_variant))
    return out
