"""The 3D web app: the Appell–Hamel mechanism (and the sliding particle) live in a browser.

Every connected browser gets its own :class:`MechanismApp` — its own controls, scene,
camera and trajectory — so students exploring at once do not change each other's view.
A control change snapshots the controls and hands them to the session's
:class:`~web.worker.LatestWorker`, which re-simulates off the GUI thread with the compiled
kernels (bursts coalesce, the newest wins) and installs the new trajectory.  One
animation thread (:class:`WebApp`) poses every session's scene at ``FPS`` and refreshes
plot markers, the time scrubber and readouts at ``REFRESH_HZ``.

Geometry lives in :mod:`web.geometry` and :mod:`web.scene`, plot data in
:mod:`web.plots`, the derived-matrices panel in :mod:`web.matrices`.

``launch()`` starts the server in the background (for ``nmkane serve``), ``main()``
blocks (``python -m web``).
"""

from __future__ import annotations

import contextlib
import math
import signal
import threading
import time
from dataclasses import dataclass

import numpy as np
import viser
import viser.uplot as uplot

from nmkane_core.errors import InputError
from nmkane_core.simulate import simulate as core_simulate
from nmkane_core.registry import get_system

from . import geometry as geo
from . import matrices as mx
from . import plots as pl
from .scene import LANES, MechanismScene, ParticleScene, mechanism_targets
from .worker import LatestWorker

FPS = 40.0                    # poses sent per second (the target is ≥ 30)
REFRESH_HZ = 4.0              # plot markers, scrubber, readouts
TARGET_ROWS = 4000            # output rows kept per run for the animation (`every`)
TIME_LIMIT_S = 10.0           # a run that takes longer stops with status 'timeout'
AH, PT = "Appell–Hamel mechanism", "Sliding particle (Example 2)"
INTEGRATORS = ("kutta-merson", "rk4", "kutta-merson-adaptive", "rk45", "dop853", "radau")
VIEWS = ("whole mechanism", "wheel", "load P")
VIEW_TARGET = {"whole mechanism": "mechanism", "wheel": "wheel", "load P": "load"}
VIEW_OFFSET = {"whole mechanism": np.array([-0.5, 0.85, 0.2]) * 42.0,     # in the body frame:
               "wheel": np.array([-0.55, 0.75, 0.36]) * 9.0,               # behind, drum side, above
               "load P": np.array([-0.45, 0.8, 0.4]) * 12.0}
PT_CAMERA = (np.array([1.2, 0.0, -0.2]), np.array([1.2, -8.3, 2.3]))   # look_at, position

# the controls' defaults: the paper's Example 1 (no stabilization) and Example 2 (Fig. 16-like)
AH_DEFAULTS = {"model": "nonlinear", "integrator": "kutta-merson", "gamma": 0.0, "gamma1": 0.0,
               "gamma2": 0.0, "log_dt": -2.0, "t_final": 20.0, "theta_dot0": 1.0, "phi_dot0": 1.0}
PT_DEFAULTS = {"pt_integrator": "kutta-merson", "pt_gamma1": -20.0, "pt_gamma2": -100.0,
               "pt_log_dt": -1.3, "pt_t_final": 300.0, "x0": 1.0}
AH_PARAM_RANGES = {"a": (0.2, 3.0, 0.05), "b": (0.05, 2.0, 0.05), "rho": (1.0, 15.0, 0.1),
                   "m": (0.1, 20.0, 0.1), "M": (0.5, 50.0, 0.5), "I": (0.1, 50.0, 0.1),
                   "g": (0.0, 20.0, 0.01), "z0": (0.0, 100.0, 1.0)}
PT_PARAM_RANGES = {"l0": (0.2, 3.0, 0.05), "m": (0.1, 10.0, 0.1), "g": (0.0, 20.0, 0.01)}
DT_MARKS = ((-4.0, "1e-4"), (-3.0, "1e-3"), (-2.0, "0.01"), (-1.0, "0.1"))
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b")
LANE_COLORS = {"M": "#2b6ed6", "N": "#dc5023", "DN": "#1ea04b"}
PT_ORDER = ("N", "DN", "M")   # series order in the particle plots


def dt_of(log_dt: float) -> float:
    """The step size of the log-scale slider, rounded to two significant digits."""
    return float(f"{10.0 ** float(log_dt):.2g}")


def _every(dt: float, t_final: float) -> int:
    return max(1, int(round(t_final / dt / TARGET_ROWS)))


def _fmt(v) -> str:
    return "—" if v is None else f"{v:.2e}"


# --------------------------------------------------------------------------- trajectories
@dataclass
class Trajectory:
    """What a session animates: the runs of one request, prepared for display."""

    kind: str                        # "ah" | "pt"
    request: dict
    runs: dict                       # label -> nmkane_core Run (first = main)
    params: dict
    plots: dict                      # plot key -> plots.Curves
    t_request: float                 # perf_counter when the controls were read
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


def _ah_plots(runs: dict) -> dict:
    labels = list(runs)
    main = runs[labels[0]]
    t = main.t
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
    out["theta"] = pl.curves(t, [np.interp(t, r.t, r.state["theta"]) for r in runs.values()],
                             [f"θ {lab} [rad]" for lab in labels])
    out["phidot"] = pl.curves(t, [np.interp(t, r.t, r.state["u2"]) for r in runs.values()],
                              [f"φ̇ {lab} [rad/s]" for lab in labels])
    return out


def _pt_plots(runs: dict) -> dict:
    t = runs["N"].t
    order = PT_ORDER
    dEs = {lab: np.interp(t, runs[lab].t, runs[lab].energy - runs[lab].energy[0]) for lab in order}
    factor, unit = pl.readable(list(dEs.values()), "J")
    return {
        "energy": pl.curves(t, [dEs[lab] / factor for lab in order], [f"ΔE {lab} [{unit}]" for lab in order]),
        "violation": pl.curves(t, [pl.log10_abs(np.interp(t, runs[lab].t, runs[lab].violation["surface"]))
                                   for lab in order], [f"{lab}" for lab in order]),
        "x": pl.curves(t, [np.interp(t, runs[lab].t, runs[lab].state["x"]) for lab in order],
                       [f"x {lab} [m]" for lab in order]),
        "y": pl.curves(t, [np.interp(t, runs[lab].t, runs[lab].state["y"]) for lab in order],
                       [f"y {lab} [m]" for lab in order]),
    }


# --------------------------------------------------------------------------- session
class MechanismApp:
    """The controls, scene, camera and trajectory of one browser (or of a test).

    ``target`` is a :class:`viser.ClientHandle` (the per-browser case) or a
    :class:`viser.ViserServer` (tests, a single shared view).  With ``sync=True`` every
    control change simulates in the calling thread (deterministic tests); otherwise a
    :class:`LatestWorker` does it in the background.
    """

    def __init__(self, target, *, simulate=core_simulate, sync: bool = False):
        self.target = target
        self.client = target if isinstance(target, viser.ClientHandle) else None
        self.gui, self.scene = target.gui, target.scene
        self._simulate = simulate
        self.lock = threading.RLock()
        self.traj: Trajectory | None = None
        self.t_now = 0.0
        self.playing = True
        self.closed = False
        self.sim_log: list[dict] = []              # settings of every simulation (tests read them)
        self.latencies: list[float] = []           # control change -> new trajectory installed, s
        self._seq = 0
        self._installs = 0
        self._quiet = False                        # while resetting: one request at the end
        self._writing_time = False
        self._shown_t = None
        self._matrices_key = None
        self._cam_offset = None                    # camera − target while following
        self._cam_reset_at = 0.0
        self._ah_params = {p.name: p.default for p in get_system("appell-hamel").parameters}
        self._pt_params = {p.name: p.default for p in get_system("sliding-particle").parameters}
        self.mechanism = MechanismScene(self.scene, self._ah_params)
        self.particle = ParticleScene(self.scene, self._pt_params["l0"])
        self._build_gui()
        self.worker = None if sync else LatestWorker(self._compute)
        if self.client is not None:
            self.client.camera.on_update(self._on_camera)
        self._aim_camera(reset=True)
        self.request()

    # ---------------------------------------------------------------- GUI
    def _build_gui(self) -> None:
        gui = self.gui
        gui.add_markdown("Nonminimal Kane's equations — Bajodah, Hodges & Chen (2005)")
        self.scene_choice = gui.add_dropdown("Scene", options=(AH, PT), initial_value=AH)
        self.status = gui.add_markdown("computing … (the first run loads the compiled kernels)")

        with gui.add_folder("Playback"):
            self.play = gui.add_button("❚❚ Pause")
            self.speed = gui.add_slider("Speed ×", min=0.1, max=20.0, step=0.1, initial_value=1.0)
            self.time = gui.add_slider("Time t [s]", min=0.0, max=20.0, step=0.01, initial_value=0.0)
            self.follow = gui.add_checkbox("Camera follows", initial_value=True)
            self.view = gui.add_dropdown("Camera target", options=VIEWS, initial_value=VIEWS[0])
            self.view_reset = gui.add_button("Reset view")

        self.ah_folder = gui.add_folder("Simulation: Appell–Hamel")
        with self.ah_folder:
            self.model = gui.add_dropdown("Constraint model", options=("nonlinear", "linear"),
                                          initial_value=AH_DEFAULTS["model"])
            self.integrator = gui.add_dropdown("Integrator", options=INTEGRATORS,
                                               initial_value=AH_DEFAULTS["integrator"])
            self.gamma = gui.add_slider("Γ (nonholonomic)", min=-50.0, max=10.0, step=0.5,
                                        initial_value=AH_DEFAULTS["gamma"])
            self.gamma1 = gui.add_slider("Γ1 (holonomic) [1/s]", min=-50.0, max=10.0, step=0.5,
                                         initial_value=AH_DEFAULTS["gamma1"])
            self.gamma2 = gui.add_slider("Γ2 (holonomic) [1/s²]", min=-500.0, max=50.0, step=5.0,
                                         initial_value=AH_DEFAULTS["gamma2"])
            self.log_dt = gui.add_slider("log₁₀ Δt [s]", min=-4.0, max=math.log10(0.2), step=0.05,
                                         initial_value=AH_DEFAULTS["log_dt"], marks=DT_MARKS,
                                         hint="step size on a log scale: −4 → 1e−4 s … −0.7 → 0.2 s")
            self.t_final = gui.add_slider("Final time [s]", min=1.0, max=200.0, step=1.0,
                                          initial_value=AH_DEFAULTS["t_final"])
            self.theta_dot0 = gui.add_slider("θ̇0 [rad/s]", min=-3.0, max=3.0, step=0.05,
                                             initial_value=AH_DEFAULTS["theta_dot0"])
            self.phi_dot0 = gui.add_slider("φ̇0 [rad/s]", min=-3.0, max=3.0, step=0.05,
                                           initial_value=AH_DEFAULTS["phi_dot0"],
                                           hint="ẋ0, ẏ0, ż0 are completed by the constraint solve")
            self.compare = gui.add_checkbox("Compare: ghost of the other model", initial_value=False)
            with gui.add_folder("Physical parameters", expand_by_default=False):
                self.params = {}
                for p in get_system("appell-hamel").parameters:
                    lo, hi, step = AH_PARAM_RANGES[p.name]
                    label = {"rho": "ρ"}.get(p.name, p.name)
                    self.params[p.name] = gui.add_slider(f"{label} [{p.unit}]", min=lo, max=hi, step=step,
                                                         initial_value=p.default, hint=p.description)
            self.reset = gui.add_button("Reset to the paper's values")

        self.pt_folder = gui.add_folder("Simulation: sliding particle", visible=False)
        with self.pt_folder:
            self.pt_integrator = gui.add_dropdown("Integrator ", options=INTEGRATORS,
                                                  initial_value=PT_DEFAULTS["pt_integrator"])
            self.pt_gamma1 = gui.add_slider("Γ1 of DN [1/s]", min=-50.0, max=10.0, step=0.5,
                                            initial_value=PT_DEFAULTS["pt_gamma1"])
            self.pt_gamma2 = gui.add_slider("Γ2 of DN [1/s²]", min=-500.0, max=50.0, step=5.0,
                                            initial_value=PT_DEFAULTS["pt_gamma2"])
            self.pt_log_dt = gui.add_slider("log₁₀ Δt [s] ", min=-4.0, max=math.log10(0.2), step=0.05,
                                            initial_value=PT_DEFAULTS["pt_log_dt"], marks=DT_MARKS)
            self.pt_t_final = gui.add_slider("Final time [s] ", min=1.0, max=3600.0, step=1.0,
                                             initial_value=PT_DEFAULTS["pt_t_final"])
            self.x0 = gui.add_slider("x0 [m]", min=-1.5, max=1.5, step=0.05, initial_value=PT_DEFAULTS["x0"])
            with gui.add_folder("Physical parameters ", expand_by_default=False):
                self.pt_params = {}
                for p in get_system("sliding-particle").parameters:
                    lo, hi, step = PT_PARAM_RANGES[p.name]
                    self.pt_params[p.name] = gui.add_slider(f"{p.name} [{p.unit}] ", min=lo, max=hi, step=step,
                                                            initial_value=p.default, hint=p.description)
            self.pt_reset = gui.add_button("Reset to the paper's values ")

        with gui.add_folder("Plots and summary"):
            self.summary = gui.add_markdown("")
            x_scale = {"x": uplot.Scale(time=False, auto=False, range=(0.0, 20.0))}
            self.plot_handles = {}
            for key, title in (("energy", "Energy drift ΔE(t)"), ("violation", "log₁₀ |constraint violation|"),
                               ("theta", "θ(t)"), ("phidot", "φ̇(t)")):
                self.plot_handles[("ah", key)] = self._add_plot(title, x_scale)
            for key, title in (("energy", "Energy drift ΔE(t) "), ("violation", "log₁₀ |ψ| (surface) "),
                               ("x", "x(t) "), ("y", "y(t) (down) ")):
                self.plot_handles[("pt", key)] = self._add_plot(title, x_scale, visible=False)

        with gui.add_folder("Derived matrices", expand_by_default=False):
            self.matrices_intro = gui.add_markdown("(computed in the background …)")
            blank = np.full((2, 2, 4), 255, np.uint8)
            self.matrix_images = {name: gui.add_image(blank, label=None, format="png", visible=False)
                                  for name in (*mx.MATRICES, "where")}
            self.matrices_latex = gui.add_markdown("", visible=False)

        # wiring: every simulation input re-simulates; playback controls do not
        sim_inputs = (self.model, self.integrator, self.gamma, self.gamma1, self.gamma2, self.log_dt,
                      self.t_final, self.theta_dot0, self.phi_dot0, self.compare, *self.params.values(),
                      self.pt_integrator, self.pt_gamma1, self.pt_gamma2, self.pt_log_dt, self.pt_t_final,
                      self.x0, *self.pt_params.values())
        for h in sim_inputs:
            h.on_update(lambda _: self.request())
        self.scene_choice.on_update(lambda _: self._on_scene())
        self.reset.on_click(lambda _: self.reset_to_paper())
        self.pt_reset.on_click(lambda _: self.reset_to_paper())
        self.play.on_click(lambda _: self.set_playing(not self.playing))
        self.time.on_update(self._on_time)
        self.view.on_update(lambda _: self.reset_view())
        self.view_reset.on_click(lambda _: self.reset_view())
        self.follow.on_update(lambda _: self._aim_camera(reset=True) if self.follow.value else None)

    def _add_plot(self, title: str, x_scale: dict, visible: bool = True):
        z = np.zeros(2)
        return self.gui.add_uplot(
            data=(z, z), series=(uplot.Series(label="t [s]"), uplot.Series(label="—", stroke=COLORS[0], width=2)),
            title=title, scales=x_scale, axes=pl.marker_axes(0.0), aspect=1.9, visible=visible)

    @property
    def kind(self) -> str:
        return "ah" if self.scene_choice.value == AH else "pt"

    # ---------------------------------------------------------------- control actions
    def set_playing(self, playing: bool) -> None:
        self.playing = bool(playing)
        self.play.label = "❚❚ Pause" if self.playing else "▶ Play"

    def reset_view(self) -> None:
        """The camera preset of the current scene and target, seen at the current heading."""
        with self.lock:
            self._aim_camera(reset=True)

    def seek(self, t: float) -> None:
        """Show time t (the scrubber, or a test)."""
        with self.lock:
            self.t_now = float(t)
            if self.traj is not None:
                self.t_now = min(max(self.t_now, 0.0), self.traj.t_end)
                self.show_time(self.t_now)
                self._refresh(force=True)

    def _on_time(self, _event) -> None:
        if not self._writing_time:                 # a person (or a test) moved the scrubber
            self.seek(float(self.time.value))

    def reset_to_paper(self) -> None:
        """Every control of the current scene back to the paper's values: one re-simulation."""
        self._quiet = True
        try:
            if self.kind == "ah":
                for name, v in AH_DEFAULTS.items():
                    getattr(self, name).value = v
                for p in get_system("appell-hamel").parameters:
                    self.params[p.name].value = p.default
                self.compare.value = False
            else:
                for name, v in PT_DEFAULTS.items():
                    getattr(self, name).value = v
                for p in get_system("sliding-particle").parameters:
                    self.pt_params[p.name].value = p.default
        finally:
            self._quiet = False
        self.request()

    def _on_scene(self) -> None:
        ah = self.kind == "ah"
        self.ah_folder.visible, self.pt_folder.visible = ah, not ah
        self.view.visible = self.follow.visible = ah
        self.mechanism.root.visible, self.particle.root.visible = ah, not ah
        for (kind, _), h in self.plot_handles.items():
            h.visible = kind == self.kind
        self.speed.value = 1.0 if ah else 5.0
        self._aim_camera(reset=True)
        self.request()

    # ---------------------------------------------------------------- simulation
    def snapshot(self) -> dict:
        """The controls now (read on the caller's thread: browser callbacks read live values)."""
        self._seq += 1
        req = {"kind": self.kind, "seq": self._seq, "t_request": time.perf_counter()}
        if req["kind"] == "ah":
            dt, t_final = dt_of(self.log_dt.value), float(self.t_final.value)
            req["compare"] = bool(self.compare.value)
            req["settings"] = {
                "system": "appell-hamel", "model": self.model.value, "integrator": self.integrator.value,
                "gamma": float(self.gamma.value), "gamma1": float(self.gamma1.value),
                "gamma2": float(self.gamma2.value), "dt": dt, "t_final": t_final,
                "every": _every(dt, t_final), "rtol": 1e-9, "atol": 1e-10,
                "initial": {"u1": float(self.theta_dot0.value), "u2": float(self.phi_dot0.value)},
                "params": {k: float(h.value) for k, h in self.params.items()}}
        else:
            dt, t_final = dt_of(self.pt_log_dt.value), float(self.pt_t_final.value)
            req["settings"] = {
                "system": "sliding-particle", "integrator": self.pt_integrator.value, "dt": dt,
                "t_final": t_final, "every": _every(dt, t_final), "rtol": 1e-9, "atol": 1e-10,
                "initial": {"x": float(self.x0.value)},
                "gamma1": float(self.pt_gamma1.value), "gamma2": float(self.pt_gamma2.value),
                "params": {k: float(h.value) for k, h in self.pt_params.items()}}
        return req

    def request(self) -> None:
        if self._quiet or self.closed:
            return
        req = self.snapshot()
        if self.worker is None:
            self._compute(req)
        else:
            self.worker.submit(req)

    def _run(self, settings: dict):
        self.sim_log.append(settings)
        return self._simulate(settings, progress=False, time_limit=TIME_LIMIT_S, cancel=self._superseded)

    def _superseded(self) -> bool:
        """A newer request is waiting (or the browser left): stop the run in progress."""
        return self.closed or (self.worker is not None and self.worker.pending is not None)

    def _compute(self, req: dict) -> None:
        """Simulate a request and install the result (the worker thread, or the caller's)."""
        t0 = time.perf_counter()
        s = req["settings"]
        try:
            if req["kind"] == "ah":
                runs = {s["model"]: self._run(s)}
                if req.get("compare"):
                    other = "linear" if s["model"] == "nonlinear" else "nonlinear"
                    runs[other] = self._run({**s, "model": other})
                plots = _ah_plots(runs)
            else:
                base = {k: v for k, v in s.items() if k not in ("gamma1", "gamma2")}
                runs = {"M": self._run({**base, "formulation": "minimal"}),
                        "N": self._run({**base, "formulation": "nonminimal"}),
                        "DN": self._run({**base, "formulation": "nonminimal",
                                         "gamma1": s["gamma1"], "gamma2": s["gamma2"]})}
                plots = _pt_plots(runs)
        except InputError as e:
            self.status.content = f"**input refused** — {e}  \nthe previous motion keeps playing"
            return
        except Exception as e:                     # never a frozen panel: say what happened
            self.status.content = f"**failed** — {type(e).__name__}: {e}"
            raise
        params = dict(next(iter(runs.values())).settings["params"])
        traj = Trajectory(req["kind"], req, runs, params, plots, req["t_request"],
                          compute_s=time.perf_counter() - t0, seq=req["seq"])
        if self._superseded() or req["kind"] != self.kind:
            return                                 # a newer request follows: show that one
        self._install(traj)

    def _install(self, traj: Trajectory) -> None:
        """Show a new trajectory: geometry that depends on it, trace, plots, summary."""
        with self.lock, self._atomic():
            if traj.kind == "ah":
                z_min = min(float(r.state["z"].min()) for r in traj.runs.values())
                self.mechanism.shape(traj.params, z_min)
                self.mechanism.set_trace(traj.main.state["x"], traj.main.state["y"])
                self.mechanism.show_ghost(len(traj.runs) > 1)
                self._matrices("appell-hamel", traj.request["settings"]["model"])
            else:
                l0 = traj.params["l0"]
                self.particle.shape(l0, max(1.6 * l0, 1.25 * abs(float(traj.request["settings"]["initial"]["x"]))))
                self._matrices("sliding-particle", "nonminimal")
            self.traj = traj
            self.t_now = min(self.t_now, traj.t_end)
            self._writing_time = True
            try:
                self.time.max = max(traj.t_end, 0.01)
            finally:
                self._writing_time = False
            self._installs += 1
            self._write_plots(traj)
            self._write_summary(traj)
            self.show_time(self.t_now)
            self._refresh(force=True)
            traj.installed_at = time.perf_counter()
            self.latencies.append(traj.installed_at - traj.t_request)
            self.status.content = self._status_text(traj)
        self.target.flush()                        # out now, not at the next 1/60 s window

    @contextlib.contextmanager
    def _atomic(self):
        with self.target.atomic():
            yield

    # ---------------------------------------------------------------- panel text
    def _status_text(self, traj: Trajectory) -> str:
        lines, groups = [], {}
        for label, run in traj.runs.items():          # runs with the same outcome share a line
            groups.setdefault((run.summary["status"], run.summary["message"]), []).append(label)
        for (status, message), labels in groups.items():
            flag = "" if status == "ok" else "⚠ "
            lines.append(f"{flag}**{', '.join(labels)}: {status}** — {message}")
        for label, run in traj.runs.items():
            s = run.summary
            for sw in s.get("switches", []):
                lines.append(f"↪ {label}: t = {sw['t']:.3f} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.1e})")
            for w in s.get("warnings", []):
                lines.append(f"⚠ {label}: {w}")
        st = traj.request["settings"]
        lines.append(f"Δt = {st['dt']:g} s · update {self._installs} (#{traj.seq}) in "
                     f"{(time.perf_counter() - traj.t_request) * 1e3:.0f} ms "
                     f"(simulation {traj.compute_s * 1e3:.0f} ms)")
        return "  \n".join(lines)

    def _write_summary(self, traj: Trajectory) -> None:
        labels = list(traj.runs)
        rows = ["| | " + " | ".join(labels) + " |", "|---|" + "---|" * len(labels)]
        rows.append("| status | " + " | ".join(r.summary["status"] for r in traj.runs.values()) + " |")
        rows.append("| max \\|ΔE\\| [J] | " + " | ".join(_fmt(r.summary["max_abs_energy_drift"])
                                                       for r in traj.runs.values()) + " |")
        names = []
        for r in traj.runs.values():
            names += [n for n in r.summary["max_abs_violation"] if n not in names]
        for n in names:
            rows.append(f"| max \\|φ\\| {n} | " + " | ".join(_fmt(r.summary["max_abs_violation"].get(n))
                                                         for r in traj.runs.values()) + " |")
        rows.append("| t_end [s] | " + " | ".join(f"{float(r.t[-1]):g}" for r in traj.runs.values()) + " |")
        self.summary.content = "\n".join(rows)

    # ---------------------------------------------------------------- plots
    def _write_plots(self, traj: Trajectory) -> None:
        end = max(traj.t_end, 1e-3)
        for key, curves in traj.plots.items():
            h = self.plot_handles[(traj.kind, key)]
            n = len(curves.ys)
            series = [uplot.Series(label="t [s]")]
            for i, lab in enumerate(curves.labels):
                if traj.kind == "pt":                          # one colour per lane: M, N, DN
                    style = {"stroke": LANE_COLORS[PT_ORDER[i]]}
                elif key == "violation":                       # one colour per constraint; other model dashed
                    per_model = len(traj.main.violation)
                    style = {"stroke": COLORS[i % per_model], **({"dash": (6.0, 4.0)} if i >= per_model else {})}
                else:                                          # main model solid, compare model dashed
                    style = {"stroke": COLORS[min(i, 1)], **({"dash": (6.0, 4.0)} if i else {})}
                series.append(uplot.Series(label=lab, width=2, **style))
            series = tuple(series)
            scales = {"x": uplot.Scale(time=False, auto=False, range=(0.0, end))}
            if tuple(h.series) != series:
                h.series = series
            if h.scales != scales:
                h.scales = scales
            h.data = curves.data()
            h.axes = pl.marker_axes(self.t_now)

    def _refresh(self, force: bool = False) -> None:
        """The slow-rate part of a frame: plot markers, scrubber, readouts."""
        traj = self.traj
        if traj is None or (not force and self._shown_t == self.t_now):
            return
        self._shown_t = self.t_now
        for key in traj.plots:
            self.plot_handles[(traj.kind, key)].axes = pl.marker_axes(self.t_now)
        self._writing_time = True
        try:
            self.time.value = round(min(self.t_now, self.time.max), 2)
        finally:
            self._writing_time = False
        if traj.kind == "pt":
            texts = []
            for lab, _, _ in LANES:
                r = traj.row(lab, self.t_now)
                psi = r["y"] + r["x"] ** 2 / traj.params["l0"] - traj.params["l0"]
                texts.append(f"ψ = {psi:+.1e} m")
            self.particle.readouts(texts)

    # ---------------------------------------------------------------- animation
    def show_time(self, t_now: float) -> None:
        """Put every node where the state at time t_now puts it (and the camera, if following)."""
        traj = self.traj
        if traj is None:
            return
        if traj.kind == "ah":
            labels = list(traj.runs)
            row = traj.row(labels[0], t_now)
            ghost = traj.row(labels[1], t_now) if len(labels) > 1 else None
            self.mechanism.pose(row, ghost)
            if self.follow.value:
                self._aim_camera(row=row)
        else:
            self.particle.pose([traj.row(lab, t_now) for lab, _, _ in LANES])

    def tick(self, dt_wall: float, refresh: bool) -> None:
        """One animation frame (called by the animation thread)."""
        if self.closed:
            return
        with self.lock:
            traj = self.traj
            if traj is None:
                return
            if self.playing:
                self.t_now += dt_wall * float(self.speed.value)
                if self.t_now > traj.t_end:
                    self.t_now = 0.0 if traj.t_end > 0 else traj.t_end
            with self._atomic():
                self.show_time(self.t_now)
            if refresh:
                self._refresh()

    # ---------------------------------------------------------------- camera
    def _aim_camera(self, reset: bool = False, row: dict | None = None) -> None:
        """Point this browser's camera: a preset view (reset), or follow the mechanism while
        keeping the viewer's own orbit and zoom.

        The offset camera − target is kept here, learnt from the browser's camera reports:
        viser's server-side camera state can be overwritten by a report the browser sent
        before it received our last pose (observed: a reset view undone a frame later), so
        reports are ignored after a reset until one shows the preset (see :meth:`_on_camera`)."""
        if self.client is None:
            return
        cam = self.client.camera
        try:
            if self.kind == "pt":
                if reset:
                    self._cam_reset_at = time.monotonic()
                    self._cam_offset = None
                    cam.position = PT_CAMERA[1]            # (moves look_at along: set it after)
                    cam.look_at = PT_CAMERA[0]
                return
            if row is None:
                traj = self.traj
                row = traj.row(next(iter(traj.runs)), self.t_now) if traj is not None and traj.kind == "ah" else \
                    {"theta": 0.0, "phi": 0.0, "x": 0.0, "y": 0.0, "z": self._ah_params["z0"]}
            target = self.mechanism.targets(row)[VIEW_TARGET[self.view.value]]
            if reset:                                  # the preset seen from the wheel's drum side
                self._cam_reset_at = time.monotonic()
                self._cam_offset = geo.rotate(geo.heading_wxyz(row["theta"]), VIEW_OFFSET[self.view.value])
            if self._cam_offset is None:
                return
            cam.position = target + self._cam_offset   # moves look_at along by the same amount
            cam.look_at = target
        except (AssertionError, ValueError):           # no camera message from the browser yet
            pass

    def _on_camera(self, cam) -> None:
        """The browser reported its camera: after it has caught up with our last preset, a
        changed offset is the viewer's own orbit or zoom, which following then keeps."""
        if self.kind == "pt":
            return
        try:
            offset = np.asarray(cam.position, float) - np.asarray(cam.look_at, float)
        except AssertionError:
            return
        if not np.all(np.isfinite(offset)) or np.linalg.norm(offset) < 1e-6:
            return
        ours = self._cam_offset
        if self._cam_reset_at:                     # waiting for the browser to show our preset
            caught_up = ours is not None and np.linalg.norm(offset - ours) <= 1e-3 * (1 + np.linalg.norm(ours))
            if not caught_up and time.monotonic() - self._cam_reset_at < 5.0:
                return                             # a report sent before our preset arrived
            self._cam_reset_at = 0.0
        self._cam_offset = offset

    # ---------------------------------------------------------------- matrices panel
    def _matrices(self, system: str, variant: str) -> None:
        key = (system, variant)
        if key == self._matrices_key:
            return
        self._matrices_key = key
        panel = mx.cached(system, variant)
        if panel is not None:
            self._show_matrices(panel)
        else:
            self.matrices_intro.content = f"(deriving the matrices of {system}, {variant} …)"
            threading.Thread(target=self._fill_matrices, args=key, daemon=True, name="nmkane-matrices").start()

    def _fill_matrices(self, system: str, variant: str) -> None:
        try:
            panel = mx.panel(system, variant)
        except Exception as e:                     # a teaching aid must never take the session down
            panel = e
        with self.lock:                            # not while the session closes
            if self._matrices_key != (system, variant) or self.closed:
                return
            if isinstance(panel, Exception):
                self.matrices_intro.content = f"(matrices unavailable: {panel})"
            else:
                self._show_matrices(panel)

    def _show_matrices(self, panel: mx.Panel) -> None:
        if self.closed:
            return
        self.matrices_intro.content = panel.intro + ("  \nn₁, … (last image) name the sums in denominators."
                                                     if panel.where is not None else "")
        imgs = {name: panel.where if name == "where" else panel.images.get(name) for name in self.matrix_images}
        width = max(i.shape[1] for i in imgs.values() if i is not None)
        for name, h in self.matrix_images.items():
            img = imgs[name]
            if img is None:
                h.visible = False
            else:                                  # one width for all: the panel scales them alike
                h.image = np.pad(img, ((0, 0), (0, width - img.shape[1]), (0, 0)), constant_values=255)
                h.visible = True
        self.matrices_latex.content = "LaTeX:\n\n```latex\n" + "\n\n".join(panel.latex.values()) + "\n```"
        self.matrices_latex.visible = True

    # ---------------------------------------------------------------- lifecycle
    def wait_idle(self, timeout: float = 30.0) -> bool:
        return True if self.worker is None else self.worker.wait_idle(timeout)

    def close(self) -> None:
        with self.lock:
            self.closed = True
        if self.worker is not None:
            self.worker.close()


# --------------------------------------------------------------------------- the server
class WebApp:
    """The viser server, one :class:`MechanismApp` per connected browser, one animation thread.

    The handle ``launch()`` returns: ``.port`` (the port actually bound) and ``.stop()``.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, simulate=core_simulate):
        self.server = viser.ViserServer(host=host, port=port, label="nmkane", verbose=False)
        self.server.gui.configure_theme(control_width="large", show_share_button=False, show_logo=False)
        self.server.scene.set_up_direction("+z")
        p = {k.name: k.default for k in get_system("appell-hamel").parameters}
        target = mechanism_targets(geo.Layout.of(p), {"theta": 0.0, "x": 0.0, "y": 0.0, "z": p["z0"]})["mechanism"]
        self.server.initial_camera.look_at = tuple(target)
        self.server.initial_camera.position = tuple(target + VIEW_OFFSET[VIEWS[0]])
        self.port = self.server.get_port()
        self.host = host
        self.sessions: dict[int, MechanismApp] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._simulate = simulate
        self.frame_times: list[float] = []
        self.frame_work_s: list[float] = []
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)
        self._warm_thread = threading.Thread(target=warm, daemon=True, name="nmkane-warm")
        self._warm_thread.start()
        self._anim = threading.Thread(target=self._animate, daemon=True, name="nmkane-animate")
        self._anim.start()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}/"

    def _connect(self, client: viser.ClientHandle) -> None:
        session = MechanismApp(client, simulate=self._simulate)
        with self._lock:
            self.sessions[client.client_id] = session

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.close()

    def _animate(self) -> None:
        period = 1.0 / FPS
        last = last_refresh = next_frame = time.perf_counter()
        while not self._stop.is_set():
            t0 = time.perf_counter()
            dt_wall, last = min(t0 - last, 0.25), t0
            refresh = t0 - last_refresh >= 1.0 / REFRESH_HZ
            if refresh:
                last_refresh = t0
            with self._lock:
                sessions = list(self.sessions.values())
            connected = self.server.get_clients()
            for s in sessions:
                if s.client is not None and s.client.client_id not in connected:
                    continue                       # gone; its disconnect callback is on the way
                try:
                    s.tick(dt_wall, refresh)
                except Exception:                  # a client gone mid-frame: skip it this frame
                    pass
            self.frame_times.append(t0)
            self.frame_work_s.append(time.perf_counter() - t0)
            del self.frame_times[:-400], self.frame_work_s[:-400]
            next_frame = max(next_frame + period, time.perf_counter())   # fixed rate, no drift
            self._stop.wait(max(0.0, next_frame - time.perf_counter()))

    def fps(self, last: int = 120) -> float:
        """Frames per second of the animation thread over the last frames."""
        ts = self.frame_times[-last:]
        return (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 2 and ts[-1] > ts[0] else 0.0

    def wait_for_session(self, timeout: float = 30.0) -> MechanismApp:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            with self._lock:
                if self.sessions:
                    return next(iter(self.sessions.values()))
            time.sleep(0.05)
        raise TimeoutError("no browser connected")

    def stop(self) -> None:
        self._stop.set()
        self._anim.join(2)
        with self._lock:
            sessions, self.sessions = list(self.sessions.values()), {}
        for s in sessions:
            s.close()
        mx.shutdown()
        self.server.stop()


def warm() -> None:
    """Load the four compiled kernels and their loops (numba loads machine code at a
    function's first call: a short run does it) and derive the matrices panels before
    anyone waits."""
    for name, variants in (("appell-hamel", ("nonlinear", "linear")), ("sliding-particle", ("nonminimal", "minimal"))):
        system = get_system(name)
        for v in variants:
            with contextlib.suppress(Exception):
                system.kernel(v)
        for v in variants:
            with contextlib.suppress(Exception):
                core_simulate({"system": name, system.option: v, "t_final": 0.05}, progress=False)
    for key in (("appell-hamel", "nonlinear"), ("sliding-particle", "nonminimal"), ("appell-hamel", "linear")):
        with contextlib.suppress(Exception):
            mx.panel(*key)


def launch(host: str = "127.0.0.1", port: int = 8080) -> WebApp:
    """Start the web app in the background; returns a handle with ``.stop()`` and ``.port``."""
    return WebApp(host=host, port=port)


def main() -> None:
    """``python -m web``: serve until Ctrl-C or SIGTERM."""
    import argparse

    ap = argparse.ArgumentParser(prog="python -m web", description="nmkane 3D web app (viser)")
    ap.add_argument("--host", default="127.0.0.1")
    ap.add_argument("--port", type=int, default=8080)
    args = ap.parse_args()
    stopping: list[int] = []               # no lock in a signal handler (see backend.serve)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: stopping.append(signum))
    app = launch(args.host, args.port)
    print(f"nmkane 3D web app {app.url}  (Ctrl-C to stop)", flush=True)
    try:
        while not stopping:
            time.sleep(0.2)
    finally:
        app.stop()
