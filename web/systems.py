"""What the page knows about each system: its controls, runs, plots and scene.

A :class:`SystemView` is the small interface between the generic page (controls, run
scheduling, plots, animation, camera) and one system.  Its class attributes are data —
the core system's name, the controls (:class:`~web.controls.Control` rows), the plots —
and its methods hold the hand-made parts: which runs a request makes (the Appell–Hamel
model and its compare ghost; the particle's M, N and DN lanes), the plot curves, and the
scene of :mod:`web.scene` (shape once per trajectory, pose per frame, camera targets).

The views are built per browser (each owns its scene nodes); :data:`VIEWS` lists their
classes in the order of the scene dropdown.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from nmkane_core.registry import get_system

from . import geometry as geo
from . import plots as pl
from .controls import INTEGRATORS, Control, log_dt_control, parameter_controls
from .scene import LANES, MechanismScene, ParticleScene, mechanism_targets

COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
LANE_COLORS = {"M": "#2b6ed6", "N": "#dc5023", "DN": "#1ea04b"}
DASH = {"dash": (6.0, 4.0)}


class SystemView:
    """One system on the page (subclasses fill in the data and the scene)."""

    kind = ""  # short key: plot handles are keyed (kind, plot)
    system = ""  # the nmkane_core system name
    title = ""  # the scene dropdown's entry
    folder = ""  # the simulation folder's title
    controls: tuple[Control, ...] = ()
    params_folder = "Physical parameters"
    params_attr = "params"  # the session's dict of parameter sliders
    reset_label = "Reset to the paper's values"
    plots: tuple[tuple[str, str], ...] = ()  # (key, title)
    speed = 1.0  # playback speed when the scene is chosen
    follows = False  # the camera can follow a target (the view dropdown applies)
    camera_views: ClassVar[dict] = {}  # view name -> camera offset (in the body frame when following)
    fixed_camera = None  # (look_at, position) when not following

    def __init__(self, scene):
        self.scene = scene
        self.params = {p.name: p.default for p in self.core.parameters}

    @property
    def core(self):
        return get_system(self.system)

    @property
    def param_controls(self) -> tuple[Control, ...]:
        return ()

    # ---------------------------------------------------------------- runs and plots
    def runs(self, settings: dict, options: dict) -> dict[str, dict]:
        """label -> the core's settings of each run one request makes (the first is the main run)."""
        return {settings[self.core.option]: settings}

    def curves(self, runs: dict) -> dict:
        raise NotImplementedError

    def series_style(self, key: str, i: int, traj) -> dict:
        return {"stroke": COLORS[i % len(COLORS)]}

    def matrices_variant(self, settings: dict) -> str:
        return settings.get(self.core.option, self.core.default_variant)

    @classmethod
    def matrices_variants(cls) -> tuple[str, ...]:
        """The models whose matrices the page may show (the first is shown first)."""
        core = get_system(cls.system)
        return (core.default_variant, *(v for v in core.variants if v != core.default_variant))

    @classmethod
    def initial_camera(cls):
        """(look_at, position) of a new browser's camera when this view is shown first, or None."""
        return

    # ---------------------------------------------------------------- scene
    root = None  # the scene node shown only while this system is chosen

    def install(self, traj) -> None:
        """Geometry that depends on the trajectory (sizes, traces)."""

    def pose(self, traj, t_now: float) -> dict | None:
        """Pose the scene at time t_now; returns the row the camera follows (or None)."""
        return None

    def readouts(self, traj, t_now: float) -> None:
        """Slow-rate labels in the scene."""

    def camera_target(self, row: dict | None, view: str) -> np.ndarray:
        raise NotImplementedError

    def rest_row(self) -> dict:
        """The row the camera aims at before there is a trajectory."""
        return {}


# --------------------------------------------------------------------------- Appell–Hamel
AH_PARAM_RANGES = {
    "a": (0.2, 3.0, 0.05),
    "b": (0.05, 2.0, 0.05),
    "rho": (1.0, 15.0, 0.1),
    "m": (0.1, 20.0, 0.1),
    "M": (0.5, 50.0, 0.5),
    "I": (0.1, 50.0, 0.1),
    "g": (0.0, 20.0, 0.01),
    "z0": (0.0, 100.0, 1.0),
}
VIEW_OFFSET = {
    "whole mechanism": np.array([-0.5, 0.85, 0.2]) * 42.0,  # in the body frame:
    "wheel": np.array([-0.55, 0.75, 0.36]) * 9.0,  # behind, drum side, above
    "load P": np.array([-0.45, 0.8, 0.4]) * 12.0,
}
VIEW_TARGET = {"whole mechanism": "mechanism", "wheel": "wheel", "load P": "load"}


class AppellHamelView(SystemView):
    """The mechanism of Example 1, with a translucent ghost of the other constraint model."""

    kind, system = "ah", "appell-hamel"
    title, folder = "Appell–Hamel mechanism", "Simulation: Appell–Hamel"
    # the paper's Example 1 (no stabilization)
    controls = (
        Control("model", "Constraint model", "variant", "nonlinear", kind="dropdown", options=("nonlinear", "linear")),
        Control("integrator", "Integrator", "integrator", "kutta-merson", kind="dropdown", options=INTEGRATORS),
        Control("gamma", "Γ (nonholonomic)", "gamma", 0.0, min=-50.0, max=10.0, step=0.5),
        Control("gamma1", "Γ1 (holonomic) [1/s]", "gamma1", 0.0, min=-50.0, max=10.0, step=0.5),
        Control("gamma2", "Γ2 (holonomic) [1/s²]", "gamma2", 0.0, min=-500.0, max=50.0, step=5.0),
        log_dt_control("log_dt", "log₁₀ Δt [s]", -2.0, hint="step size on a log scale: −4 → 1e−4 s … −0.7 → 0.2 s"),
        Control("t_final", "Final time [s]", "t_final", 20.0, min=1.0, max=200.0, step=1.0),
        Control("theta_dot0", "θ̇0 [rad/s]", "initial.u1", 1.0, min=-3.0, max=3.0, step=0.05),
        Control(
            "phi_dot0",
            "φ̇0 [rad/s]",
            "initial.u2",
            1.0,
            min=-3.0,
            max=3.0,
            step=0.05,
            hint="ẋ0, ẏ0, ż0 are completed by the constraint solve",
        ),
        Control("compare", "Compare: ghost of the other model", "option.compare", False, kind="checkbox"),
    )
    plots = (
        ("energy", "Energy drift ΔE(t)"),
        ("violation", "log₁₀ |constraint violation|"),
        ("theta", "θ(t)"),
        ("phidot", "φ̇(t)"),
    )
    speed, follows = 1.0, True
    camera_views = VIEW_OFFSET

    def __init__(self, scene):
        super().__init__(scene)
        self.mechanism = MechanismScene(scene, self.params)
        self.root = self.mechanism.root

    @property
    def param_controls(self) -> tuple[Control, ...]:
        return parameter_controls(self.core, AH_PARAM_RANGES, {"rho": "ρ"})

    def runs(self, settings: dict, options: dict) -> dict[str, dict]:
        runs = {settings["model"]: settings}
        if options.get("compare"):
            other = "linear" if settings["model"] == "nonlinear" else "nonlinear"
            runs[other] = {**settings, "model": other}
        return runs

    def curves(self, runs: dict) -> dict:
        labels = list(runs)
        t = runs[labels[0]].t
        out = {}
        dEs = {lab: np.interp(t, r.t, r.energy - r.energy[0]) for lab, r in runs.items()}
        factor, unit = pl.readable(list(dEs.values()), "J")
        out["energy"] = pl.curves(t, [dEs[lab] / factor for lab in labels], [f"ΔE {lab} [{unit}]" for lab in labels])
        ys, names = [], []
        for lab, r in runs.items():
            for c, v in r.violation.items():
                ys.append(pl.log10_abs(np.interp(t, r.t, v)))
                names.append(f"{c}" if lab == labels[0] else f"{c} ({lab})")
        out["violation"] = pl.curves(t, ys, names)
        out["theta"] = pl.curves(
            t, [np.interp(t, r.t, r.state["theta"]) for r in runs.values()], [f"θ {lab} [rad]" for lab in labels]
        )
        out["phidot"] = pl.curves(
            t, [np.interp(t, r.t, r.state["u2"]) for r in runs.values()], [f"φ̇ {lab} [rad/s]" for lab in labels]
        )
        return out

    def series_style(self, key: str, i: int, traj) -> dict:
        if key == "violation":  # one colour per constraint; other model dashed
            per_model = len(traj.main.violation)
            return {"stroke": COLORS[i % per_model], **(DASH if i >= per_model else {})}
        return {"stroke": COLORS[min(i, 1)], **(DASH if i else {})}  # main solid, compare dashed

    def install(self, traj) -> None:
        z_min = min(float(r.state["z"].min()) for r in traj.runs.values())
        self.mechanism.shape(traj.params, z_min)
        self.mechanism.set_trace(traj.main.state["x"], traj.main.state["y"])
        self.mechanism.show_ghost(len(traj.runs) > 1)

    def pose(self, traj, t_now: float) -> dict:
        labels = list(traj.runs)
        row = traj.row(labels[0], t_now)
        ghost = traj.row(labels[1], t_now) if len(labels) > 1 else None
        self.mechanism.pose(row, ghost)
        return row

    def rest_row(self) -> dict:
        return {"theta": 0.0, "phi": 0.0, "x": 0.0, "y": 0.0, "z": self.params["z0"]}

    @classmethod
    def initial_camera(cls):
        p = {k.name: k.default for k in get_system(cls.system).parameters}
        rest = {"theta": 0.0, "x": 0.0, "y": 0.0, "z": p["z0"]}
        target = mechanism_targets(geo.Layout.of(p), rest)[VIEW_TARGET["whole mechanism"]]
        return tuple(target), tuple(target + VIEW_OFFSET["whole mechanism"])

    def camera_target(self, row: dict, view: str) -> np.ndarray:
        return self.mechanism.targets(row)[VIEW_TARGET[view]]

    def camera_offset(self, row: dict, view: str) -> np.ndarray:
        """The preset offset camera − target, seen from the wheel's drum side at the row's heading."""
        return geo.rotate(geo.heading_wxyz(row["theta"]), VIEW_OFFSET[view])


# --------------------------------------------------------------------------- sliding particle
PT_PARAM_RANGES = {"l0": (0.2, 3.0, 0.05), "m": (0.1, 10.0, 0.1), "g": (0.0, 20.0, 0.01)}
PT_ORDER = ("N", "DN", "M")  # series order in the particle plots


class ParticleView(SystemView):
    """Example 2: the minimal (M), nonminimal (N) and damped nonminimal (DN) solutions side by side."""

    kind, system = "pt", "sliding-particle"
    title, folder = "Sliding particle (Example 2)", "Simulation: sliding particle"
    # (labels end in a space where they would repeat the Appell–Hamel folder's: one page, two folders)
    # the paper's Fig. 16-like run
    controls = (
        Control("pt_integrator", "Integrator ", "integrator", "kutta-merson", kind="dropdown", options=INTEGRATORS),
        Control("pt_gamma1", "Γ1 of DN [1/s]", "gamma1", -20.0, min=-50.0, max=10.0, step=0.5),
        Control("pt_gamma2", "Γ2 of DN [1/s²]", "gamma2", -100.0, min=-500.0, max=50.0, step=5.0),
        log_dt_control("pt_log_dt", "log₁₀ Δt [s] ", -1.3),
        Control("pt_t_final", "Final time [s] ", "t_final", 300.0, min=1.0, max=3600.0, step=1.0),
        Control("x0", "x0 [m]", "initial.x", 1.0, min=-1.5, max=1.5, step=0.05),
    )
    params_folder, params_attr = "Physical parameters ", "pt_params"
    reset_label = "Reset to the paper's values "
    plots = (
        ("energy", "Energy drift ΔE(t) "),
        ("violation", "log₁₀ |ψ| (surface) "),
        ("x", "x(t) "),
        ("y", "y(t) (down) "),
    )
    speed = 5.0
    fixed_camera = (np.array([1.2, 0.0, -0.2]), np.array([1.2, -8.3, 2.3]))  # look_at, position

    def __init__(self, scene):
        super().__init__(scene)
        self.particle = ParticleScene(scene, self.params["l0"])
        self.root = self.particle.root

    @property
    def param_controls(self) -> tuple[Control, ...]:
        return parameter_controls(self.core, PT_PARAM_RANGES, suffix=" ")

    def runs(self, settings: dict, options: dict) -> dict[str, dict]:
        base = {k: v for k, v in settings.items() if k not in ("gamma1", "gamma2")}
        return {
            "M": {**base, "formulation": "minimal"},
            "N": {**base, "formulation": "nonminimal"},
            "DN": {**base, "formulation": "nonminimal", "gamma1": settings["gamma1"], "gamma2": settings["gamma2"]},
        }

    def curves(self, runs: dict) -> dict:
        t = runs["N"].t
        order = PT_ORDER
        dEs = {lab: np.interp(t, runs[lab].t, runs[lab].energy - runs[lab].energy[0]) for lab in order}
        factor, unit = pl.readable(list(dEs.values()), "J")
        return {
            "energy": pl.curves(t, [dEs[lab] / factor for lab in order], [f"ΔE {lab} [{unit}]" for lab in order]),
            "violation": pl.curves(
                t,
                [pl.log10_abs(np.interp(t, runs[lab].t, runs[lab].violation["surface"])) for lab in order],
                [f"{lab}" for lab in order],
            ),
            "x": pl.curves(
                t, [np.interp(t, runs[lab].t, runs[lab].state["x"]) for lab in order], [f"x {lab} [m]" for lab in order]
            ),
            "y": pl.curves(
                t, [np.interp(t, runs[lab].t, runs[lab].state["y"]) for lab in order], [f"y {lab} [m]" for lab in order]
            ),
        }

    def series_style(self, key: str, i: int, traj) -> dict:
        return {"stroke": LANE_COLORS[PT_ORDER[i]]}  # one colour per lane: M, N, DN

    def matrices_variant(self, settings: dict) -> str:
        return "nonminimal"

    @classmethod
    def matrices_variants(cls) -> tuple[str, ...]:
        return ("nonminimal",)

    def install(self, traj) -> None:
        l0 = traj.params["l0"]
        self.particle.shape(l0, max(1.6 * l0, 1.25 * abs(float(traj.request["settings"]["initial"]["x"]))))

    def pose(self, traj, t_now: float) -> None:
        self.particle.pose([traj.row(lab, t_now) for lab, _, _ in LANES])

    def readouts(self, traj, t_now: float) -> None:
        texts = []
        for lab, _, _ in LANES:
            r = traj.row(lab, t_now)
            psi = r["y"] + r["x"] ** 2 / traj.params["l0"] - traj.params["l0"]
            texts.append(f"ψ = {psi:+.1e} m")
        self.particle.readouts(texts)


VIEWS = (AppellHamelView, ParticleView)


def scene_choices() -> dict[str, str]:
    """The scene dropdown: title -> system name for every registered system (built-in,
    catalogue, plugged in); the hand-made views first, under their own titles."""
    from nmkane_core.registry import system_names

    out = {cls.title: cls.system for cls in VIEWS}
    made = set(out.values())
    for name in system_names():
        if name in made:
            continue
        try:
            title = get_system(name).title or name
        except Exception:  # a broken plug-in: listed by name, reported when chosen
            title = name
        out[title if title not in out else f"{title} ({name})"] = name
    return out
