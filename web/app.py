"""The 3D web app: the Appell–Hamel mechanism (and the sliding particle) live in a browser.

Every connected browser gets its own :class:`Session` — its own controls, scene and
trajectory — so students exploring at once do not change each other's view.  A slider
change is snapshotted and handed to the session's :class:`LatestWorker`, which coalesces
bursts (a drag fires one event per step) and re-simulates off the GUI thread with the
compiled kernels; one animation thread moves every session's scene at 30 frames per
second and refreshes the plots a few times per second.

Scene tree (geometry in :mod:`web.geometry`, animation here)::

    /ah/frame                  pose = P's horizontal position, heading θ
    /ah/frame/wheel/spin       the wheel's spin φ about its axle (child of the heading frame)
    /ah/frame/load, /thread    the hanging load and the thread over the pulleys
    /ah/ghost/...              the other constraint model (compare), translucent
    /ah/trace                  P's intercept on the plane (the paper's Fig. 7)
    /pt/lane{0,1,2}/particle   minimal | undamped nonminimal | damped nonminimal
"""

from __future__ import annotations

import math
import signal
import threading
import time
from dataclasses import dataclass, field

import numpy as np
import viser
import viser.uplot as uplot

from nmkane_core.errors import InputError
from nmkane_core.simulate import simulate as core_simulate
from nmkane_core.system import get_system

from . import geometry as geo

FPS = 30.0
PLOT_HZ = 4.0
AH_PARAMS = ("a", "b", "rho", "m", "M", "I", "g")
INTEGRATORS = ("kutta-merson", "rk4", "kutta-merson-adaptive", "dop853", "rk45")


# --------------------------------------------------------------------------- workers
class LatestWorker:
    """Runs ``fn`` on the newest submitted request only (bursts coalesce), off the GUI thread."""

    def __init__(self, fn, debounce: float = 0.02):
        self.fn, self.debounce = fn, debounce
        self.cv = threading.Condition()
        self.pending = None
        self.busy = False
        self.closed = False
        self.thread = threading.Thread(target=self._run, daemon=True, name="nmkane-resim")
        self.thread.start()

    def submit(self, request) -> None:
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
            time.sleep(self.debounce)            # let a slider drag settle, keep the newest
            with self.cv:
                request, self.pending = self.pending, None
            try:
                self.fn(request)
            finally:
                with self.cv:
                    self.busy = False
                    self.cv.notify_all()

    def wait_idle(self, timeout: float = 30.0) -> bool:
        end = time.time() + timeout
        with self.cv:
            while self.pending is not None or self.busy:
                left = end - time.time()
                if left <= 0:
                    return False
                self.cv.wait(left)
        return True

    def close(self) -> None:
        with self.cv:
            self.closed = True
            self.cv.notify_all()
        self.thread.join(5)


# --------------------------------------------------------------------------- matrices
_MATRIX_TEXT: dict = {}
_MATRIX_LOCK = threading.Lock()


def matrices_markdown(system: str, variant: str) -> str:
    """The derived A1, A2 and T of a model as readable text (cached, computed once)."""
    key = (system, variant)
    with _MATRIX_LOCK:
        if key in _MATRIX_TEXT:
            return _MATRIX_TEXT[key]
    import sympy as sp

    d = get_system(system).derivation(variant)
    parts = [f"**{system}, {variant}** — nonminimal equations T u̇ = V̂ (44), speeds "
             f"[u_I, u_D] = {[str(s) for s in d.u_perm]}"]
    for name, title in (("A1", "A1 = [−A  I]  (22)"), ("A2", "A2 = [I  Aᵀ]  (40)"), ("T", "T = [A1; A2 Q]  (44)")):
        mat = d.matrix(name).applyfunc(lambda e: sp.simplify(e) if sp.count_ops(e) < 120 else e)
        text = sp.pretty(mat, use_unicode=True, wrap_line=False)
        parts.append(f"{title}\n```\n{text}\n```")
    md = "\n\n".join(parts)
    with _MATRIX_LOCK:
        _MATRIX_TEXT[key] = md
    return md


# --------------------------------------------------------------------------- trajectories
@dataclass
class Trajectory:
    """What a session animates: the runs of one request, and when they were computed."""

    kind: str                       # "ah" | "pt"
    settings: dict
    runs: dict                      # label -> nmkane_core Run
    params: dict
    computed_at: float = field(default_factory=time.time)
    compute_s: float = 0.0

    @property
    def main(self):
        return next(iter(self.runs.values()))

    @property
    def t_end(self) -> float:
        return float(self.main.t[-1])


def _status_line(run) -> str:
    s = run.summary
    return f"**{s['status']}** — {s['message']}"


# --------------------------------------------------------------------------- session
class Session:
    """The controls, scene and trajectory of one browser (or of a test)."""

    def __init__(self, gui, scene, *, client=None, simulate=core_simulate, sync: bool = False):
        self.gui, self.scene, self.client = gui, scene, client
        self._simulate = simulate
        self.lock = threading.Lock()
        self.traj: Trajectory | None = None
        self.anim_t = 0.0
        self.last_error = ""
        self.sim_log: list[dict] = []          # settings of every simulation (tests read it)
        self._build_gui()
        self._build_scene()
        self.worker = None if sync else LatestWorker(self._compute)
        self.request()

    # ---------------------------------------------------------------- GUI
    def _build_gui(self) -> None:
        gui = self.gui
        ah = get_system("appell-hamel")
        self.scene_choice = gui.add_dropdown("Scene", options=("Appell–Hamel", "Sliding particle"),
                                             initial_value="Appell–Hamel")
        self.status = gui.add_markdown("computing …")
        with gui.add_folder("Playback"):
            self.playing = gui.add_checkbox("Play", initial_value=True)
            self.speed = gui.add_slider("Speed ×", min=0.1, max=10.0, step=0.1, initial_value=1.0)
            self.scrub = gui.add_slider("Time t [s]", min=0.0, max=20.0, step=0.01, initial_value=0.0)
            self.follow = gui.add_checkbox("Camera follows", initial_value=True)
            self.cam_dist = gui.add_slider("Camera distance [m]", min=5.0, max=120.0, step=1.0, initial_value=19.0)
        self.ah_folder = gui.add_folder("Appell–Hamel")
        with self.ah_folder:
            self.model = gui.add_dropdown("Constraint model", options=("nonlinear", "linear"),
                                          initial_value="nonlinear")
            self.integrator = gui.add_dropdown("Integrator", options=INTEGRATORS, initial_value="kutta-merson")
            self.gamma = gui.add_slider("Γ (nonholonomic)", min=-50.0, max=10.0, step=0.5, initial_value=0.0)
            self.log_dt = gui.add_slider("log10 Δt [s]", min=-4.0, max=math.log10(0.2), step=0.05,
                                         initial_value=-2.0)
            self.t_final = gui.add_slider("Final time [s]", min=1.0, max=200.0, step=1.0, initial_value=20.0)
            self.theta_dot0 = gui.add_slider("θ̇0 [rad/s]", min=-3.0, max=3.0, step=0.05, initial_value=1.0)
            self.phi_dot0 = gui.add_slider("φ̇0 [rad/s]", min=-3.0, max=3.0, step=0.05, initial_value=1.0)
            self.compare = gui.add_checkbox("Compare: ghost of the other model", initial_value=False)
            with gui.add_folder("Physical parameters", expand_by_default=False):
                self.params = {p.name: gui.add_slider(f"{p.name} [{p.unit}]" if p.unit else p.name,
                                                      min=max(p.min, 0.0) + (0.05 if not p.min_inclusive else 0.0),
                                                      max=min(p.max, 4 * p.default + 1), step=0.05,
                                                      initial_value=p.default)
                               for p in ah.parameters if p.name in AH_PARAMS}
            self.reset = gui.add_button("Reset to the paper's values")
        self.pt_folder = gui.add_folder("Sliding particle", visible=False)
        with self.pt_folder:
            self.gamma1 = gui.add_slider("Γ1 [1/s]", min=-50.0, max=10.0, step=0.5, initial_value=-20.0)
            self.gamma2 = gui.add_slider("Γ2 [1/s²]", min=-500.0, max=50.0, step=5.0, initial_value=-100.0)
            self.pt_log_dt = gui.add_slider("log10 Δt [s] ", min=-4.0, max=math.log10(0.2), step=0.05,
                                            initial_value=-2.0)
            self.pt_t_final = gui.add_slider("Final time [s] ", min=1.0, max=500.0, step=1.0, initial_value=60.0)
            self.x0 = gui.add_slider("x0 [m]", min=-1.5, max=1.5, step=0.05, initial_value=1.0)
        with gui.add_folder("Plots"):
            x_scale = {"x": uplot.Scale(time=False, auto=False, range=(0.0, 20.0))}
            z2 = (np.zeros(2), np.zeros(2))
            self.plot_energy = gui.add_uplot(data=z2, series=(
                uplot.Series(label="t [s]"), uplot.Series(label="ΔE [J]", stroke="#1f77b4", width=2)),
                title="Energy drift ΔE(t)", scales=dict(x_scale), aspect=2.0)
            self.plot_viol = gui.add_uplot(data=z2 + (np.zeros(2), np.zeros(2)), series=(
                uplot.Series(label="t [s]"), uplot.Series(label="c1", stroke="#2ca02c", width=2),
                uplot.Series(label="c2", stroke="#ff7f0e", width=2), uplot.Series(label="c3", stroke="#9467bd", width=2)),
                title="log10 |constraint violation|", scales=dict(x_scale), aspect=2.0)
            self.plot_state = gui.add_uplot(data=z2 + (np.zeros(2),), series=(
                uplot.Series(label="t [s]"), uplot.Series(label="θ [rad]", stroke="#8c564b", width=2),
                uplot.Series(label="φ̇ [rad/s]", stroke="#e377c2", width=2)),
                title="θ(t) and φ̇(t)", scales=dict(x_scale), aspect=2.0)
        with gui.add_folder("Derived matrices", expand_by_default=False):
            self.matrices = gui.add_markdown("(computed in the background …)")

        for h in (self.model, self.integrator, self.gamma, self.log_dt, self.t_final, self.theta_dot0,
                  self.phi_dot0, self.compare, self.gamma1, self.gamma2, self.pt_log_dt, self.pt_t_final,
                  self.x0, *self.params.values()):
            h.on_update(lambda _: self.request())
        self.scene_choice.on_update(lambda _: self._on_scene())
        self.reset.on_click(lambda _: self._reset())
        self.scrub.on_update(self._on_scrub)

    def _reset(self) -> None:
        ah = get_system("appell-hamel")
        for p in ah.parameters:
            if p.name in self.params:
                self.params[p.name].value = p.default
        self.gamma.value, self.log_dt.value, self.t_final.value = 0.0, -2.0, 20.0
        self.theta_dot0.value, self.phi_dot0.value = 1.0, 1.0
        self.model.value, self.integrator.value = "nonlinear", "kutta-merson"
        self.gamma1.value, self.gamma2.value, self.x0.value = -20.0, -100.0, 1.0
        self.request()

    def _on_scene(self) -> None:
        is_ah = self.scene_choice.value == "Appell–Hamel"
        self.ah_folder.visible = is_ah
        self.pt_folder.visible = not is_ah
        self.ah_root.visible = is_ah
        self.pt_root.visible = not is_ah
        self.request()

    def _on_scrub(self, event) -> None:
        if event.client is not None or not self.playing.value:   # a person moved the scrubber
            with self.lock:
                self.anim_t = float(self.scrub.value)

    # ---------------------------------------------------------------- scene
    def _build_scene(self) -> None:
        sc = self.scene
        self.ah_root = sc.add_frame("/ah", show_axes=False)
        sc.add_grid("/ah/ground", width=300.0, height=300.0, plane="xy", cell_size=5.0, section_size=25.0,
                    infinite_grid=True, fade_distance=250.0)
        self.trace = sc.add_line_segments("/ah/trace", points=np.zeros((1, 2, 3), np.float32),
                                          colors=(220, 60, 30), thickness=0.25)
        self.frame = sc.add_frame("/ah/frame", show_axes=False)
        self.ghost = sc.add_frame("/ah/ghost", show_axes=False, visible=False)
        self._frame_parts = {}
        self._shape_frame(geo_params=get_system("appell-hamel").resolve_params({}), z_min=0.0)
        self.pt_root = sc.add_frame("/pt", show_axes=False, visible=False)
        self.pt_particles = []
        for i, (label, color) in enumerate((("M  minimal (137)", (40, 120, 220)),
                                             ("N  nonminimal, Γ1 = Γ2 = 0", (220, 90, 40)),
                                             ("DN damped nonminimal", (40, 170, 80)))):
            sc.add_frame(f"/pt/lane{i}", show_axes=False, position=(3.8 * (i - 1), 0.0, 0.0))
            sc.add_label(f"/pt/lane{i}/label", label, position=(-0.9, 0.0, 1.9))
            self.pt_particles.append(sc.add_icosphere(f"/pt/lane{i}/particle", radius=0.07, color=color))
        self._shape_troughs(1.0)

    def _shape_frame(self, geo_params: dict, z_min: float) -> None:
        """(Re)build the frame, wheel and pulleys for the parameters (sizes are geometry)."""
        sc, p = self.scene, geo_params
        h = geo.pulley_height(p)
        a, b, rho = p["a"], p["b"], p["rho"]
        axle = (math.cos(math.pi / 4), math.sin(math.pi / 4), 0.0, 0.0)   # cylinder axis z -> y
        bottom = min(z_min - 1.0, -1.0)
        for root, opacity in (("/ah/frame", None), ("/ah/ghost", 0.35)):
            full = root == "/ah/frame"
            if full:
                sc.add_box(f"{root}/beam", dimensions=(rho, 0.18, 0.18), color=(110, 110, 120),
                           position=(-rho / 2, 0.0, h))
                sc.add_box(f"{root}/leg", dimensions=(0.18, 0.18, h), color=(110, 110, 120),
                           position=(-rho, a * 0.9 + 0.4, h / 2))
                sc.add_box(f"{root}/leg_beam", dimensions=(0.18, a * 0.9 + 0.4, 0.18), color=(110, 110, 120),
                           position=(-rho, (a * 0.9 + 0.4) / 2, h))
                sc.add_box(f"{root}/bar", dimensions=(0.12, 0.12, h - bottom), color=(150, 150, 160),
                           position=(0.0, 0.0, (h + bottom) / 2))
                sc.add_box(f"{root}/shaft", dimensions=(0.9, 0.9, -bottom), color=(40, 40, 40), opacity=0.35,
                           position=(0.0, 0.0, bottom / 2))
                for name, xp in (("pulley_wheel", -rho), ("pulley_bar", 0.0)):
                    sc.add_cylinder(f"{root}/{name}", radius=0.35, height=0.15, color=(200, 160, 40),
                                    wxyz=axle, position=(xp, 0.0, h))
            sc.add_frame(f"{root}/wheel", show_axes=False, position=geo.wheel_centre_local(p))
            spin = sc.add_frame(f"{root}/wheel/spin", show_axes=False)
            sc.add_cylinder(f"{root}/wheel/spin/disk", radius=a, height=0.12 * a + 0.05, color=(60, 90, 200),
                            wxyz=axle, opacity=opacity)
            sc.add_cylinder(f"{root}/wheel/spin/drum", radius=b, height=0.35 * a + 0.1, color=(230, 200, 60),
                            wxyz=axle, opacity=opacity)
            sc.add_box(f"{root}/wheel/spin/spoke", dimensions=(1.9 * a, 0.2 * a + 0.05, 0.12 * a),
                       color=(240, 240, 240), opacity=opacity)
            load = sc.add_icosphere(f"{root}/load", radius=0.45, color=(30, 170, 60), opacity=opacity)
            thread = sc.add_line_segments(f"{root}/thread", points=geo.thread_local(p, p["z0"]),
                                          colors=(20, 20, 20), thickness=0.06)
            self._frame_parts[root] = {"spin": spin, "load": load, "thread": thread}
        self._shaped_for = (dict(p), bottom)

    def _shape_troughs(self, l0: float) -> None:
        verts, faces = geo.parabola_trough(l0)
        for i in range(3):
            self.scene.add_mesh_simple(f"/pt/lane{i}/trough", verts, faces, color=(180, 190, 200),
                                       opacity=0.6, side="double")

    # ---------------------------------------------------------------- simulation
    def current_request(self) -> dict:
        """A snapshot of the controls (taken on the GUI thread; values are read live)."""
        if self.scene_choice.value == "Appell–Hamel":
            dt = 10 ** self.log_dt.value
            t_final = float(self.t_final.value)
            return {"kind": "ah", "compare": bool(self.compare.value), "settings": {
                "system": "appell-hamel", "model": self.model.value, "integrator": self.integrator.value,
                "gamma": float(self.gamma.value), "dt": dt, "t_final": t_final,
                "every": max(1, int(round(t_final / dt / 3000))), "rtol": 1e-9, "atol": 1e-10,
                "initial": {"u1": float(self.theta_dot0.value), "u2": float(self.phi_dot0.value)},
                "params": {k: float(h.value) for k, h in self.params.items()}}}
        dt = 10 ** self.pt_log_dt.value
        t_final = float(self.pt_t_final.value)
        return {"kind": "pt", "settings": {
            "system": "sliding-particle", "dt": dt, "t_final": t_final,
            "every": max(1, int(round(t_final / dt / 3000))), "initial": {"x": float(self.x0.value)},
            "gamma1": float(self.gamma1.value), "gamma2": float(self.gamma2.value)}}

    def request(self) -> None:
        req = self.current_request()
        if self.worker is None:
            self._compute(req)
        else:
            self.worker.submit(req)

    def _compute(self, req: dict) -> None:
        t0 = time.perf_counter()
        s = req["settings"]
        try:
            if req["kind"] == "ah":
                runs = {s["model"]: self._run(s)}
                if req.get("compare"):
                    other = "linear" if s["model"] == "nonlinear" else "nonlinear"
                    runs[other] = self._run({**s, "model": other})
                params = runs[s["model"]].settings["params"]
            else:
                base = {k: v for k, v in s.items() if k not in ("gamma1", "gamma2")}
                runs = {"M": self._run({**base, "formulation": "minimal"}),
                        "N": self._run({**base, "formulation": "nonminimal"}),
                        "DN": self._run({**base, "formulation": "nonminimal", "gamma1": s["gamma1"],
                                         "gamma2": s["gamma2"]})}
                params = runs["N"].settings["params"]
        except InputError as e:
            self.last_error = str(e)
            self.status.content = f"**input refused** — {e}"
            return
        traj = Trajectory(req["kind"], s, runs, params, compute_s=time.perf_counter() - t0)
        self._install(traj)

    def _run(self, settings: dict):
        self.sim_log.append(settings)
        return self._simulate(settings, progress=False, time_limit=10.0)

    def _install(self, traj: Trajectory) -> None:
        """Show a new trajectory: geometry that depends on it, plots, summary; restart time."""
        if traj.kind == "ah":
            main = traj.main
            z_min = float(min(r.state["z"].min() for r in traj.runs.values()))
            if self._shaped_for[0] != traj.params or z_min - 1.0 < self._shaped_for[1] - 0.5 \
                    or z_min - 1.0 > self._shaped_for[1] + 20:
                self._shape_frame(traj.params, z_min)
            idx = geo.decimate(len(main.t), 4000)
            pts = np.column_stack([main.state["x"][idx], main.state["y"][idx], np.full(len(idx), 0.03)])
            self.trace.points = np.stack([pts[:-1], pts[1:]], axis=1).astype(np.float32) if len(pts) > 1 \
                else np.zeros((1, 2, 3), np.float32)
            self.ghost.visible = len(traj.runs) > 1
            threading.Thread(target=self._fill_matrices, args=("appell-hamel", traj.settings["model"]),
                             daemon=True).start()
        else:
            self._shape_troughs(traj.params["l0"])
            threading.Thread(target=self._fill_matrices, args=("sliding-particle", "nonminimal"),
                             daemon=True).start()
        with self.lock:
            self.traj = traj
            self.anim_t = 0.0
        self.scrub.max = max(traj.t_end, 0.01)
        self._write_summary(traj)
        self._write_plots(traj, 0.0)
        self.show_time(0.0)

    def _fill_matrices(self, system: str, variant: str) -> None:
        try:
            self.matrices.content = matrices_markdown(system, variant)
        except Exception as e:  # a display aid must never take the session down
            self.matrices.content = f"(matrices unavailable: {e})"

    def _write_summary(self, traj: Trajectory) -> None:
        lines = []
        for label, run in traj.runs.items():
            s = run.summary
            viol = ", ".join(f"{k} {v:.2e}" for k, v in s["max_abs_violation"].items())
            de = "—" if s["max_abs_energy_drift"] is None else f"{s['max_abs_energy_drift']:.2e}"
            lines.append(f"**{label}**: {_status_line(run)}  \nmax \\|ΔE\\| {de}; max \\|φ\\| {viol}")
            for sw in s.get("switches", []):
                lines.append(f"  ↪ t = {sw['t']:.3f} s: {sw['from']} → {sw['to']} (rcond {sw['rcond']:.1e})")
            for w in s.get("warnings", []):
                lines.append(f"  ⚠ {w}")
        lines.append(f"computed in {traj.compute_s * 1e3:.0f} ms")
        self.last_error = ""
        self.status.content = "\n\n".join(lines)

    # ---------------------------------------------------------------- plots
    def _write_plots(self, traj: Trajectory, t_now: float) -> None:
        """Curves drawn up to the animation's current time (the curve's end is "now"),
        on a time axis fixed to the whole run; tiny values rescaled so ticks stay readable."""
        def upto(run):
            idx = geo.decimate(len(run.t), 1500)
            k = int(np.searchsorted(run.t[idx], t_now, side="right"))
            return idx[:max(k, 2)]

        def scaled(y, unit):
            big = float(np.abs(y).max()) if len(y) else 0.0
            if big == 0.0 or 1e-2 <= big < 1e4:
                return y, unit
            e = int(math.floor(math.log10(big)))
            return y / 10.0 ** e, f"×1e{e} {unit}"

        end = max(traj.t_end, 1e-3)
        if traj.kind == "ah":
            run = traj.main
            full_dE = run.energy - run.energy[0]
            _, unit = scaled(full_dE, "J")
            e = 0 if "×1e" not in unit else int(unit.split("×1e")[1].split()[0])
            idx = upto(run)
            t = run.t[idx]
            names = list(run.violation)
            logs = [np.log10(np.maximum(np.abs(run.violation[n][idx]), 1e-17)) for n in names]
            while len(logs) < 3:
                logs.append(logs[-1])
                names.append("—")
            data = [(self.plot_energy, (t, full_dE[idx] / 10.0 ** e), ("t [s]", f"ΔE [{unit}]")),
                    (self.plot_viol, (t, *logs[:3]), ("t [s]", *names[:3])),
                    (self.plot_state, (t, run.state["theta"][idx], run.state["u2"][idx]),
                     ("t [s]", "θ [rad]", "φ̇ [rad/s]"))]
        else:
            n, dn = traj.runs["N"], traj.runs["DN"]
            idx = upto(n)
            t = n.t[idx]
            dE = n.energy - n.energy[0]
            _, unit = scaled(np.concatenate([dE, dn.energy - dn.energy[0]]), "J")
            e = 0 if "×1e" not in unit else int(unit.split("×1e")[1].split()[0])
            data = [(self.plot_energy, (t, dE[idx] / 10.0 ** e), ("t [s]", f"ΔE N [{unit}]")),
                    (self.plot_viol, (t, np.log10(np.maximum(np.abs(n.violation["surface"][idx]), 1e-17)),
                                      np.log10(np.maximum(np.abs(dn.violation["surface"][idx]), 1e-17)),
                                      np.log10(np.maximum(np.abs(traj.runs["M"].violation["surface"][idx]), 1e-17))),
                     ("t [s]", "N (undamped)", "DN (damped)", "M (minimal)")),
                    (self.plot_state, (t, n.state["y"][idx], dn.state["y"][idx]), ("t [s]", "y N [m]", "y DN [m]"))]
        for plot, arrays, labels in data:
            if plot.scales["x"].get("range") != (0.0, end):
                plot.scales = {"x": uplot.Scale(time=False, auto=False, range=(0.0, end))}
            series = tuple({**ser, "label": lab} for ser, lab in zip(plot.series, labels))
            if series != tuple(plot.series):
                plot.series = series
            plot.data = tuple(np.asarray(a, float) for a in arrays)
        self.plots_t = t_now

    # ---------------------------------------------------------------- animation
    def advance(self, dt_wall: float) -> float:
        with self.lock:
            if self.traj is None:
                return 0.0
            if self.playing.value:
                self.anim_t += dt_wall * float(self.speed.value)
                if self.anim_t > self.traj.t_end:
                    self.anim_t = 0.0
            return self.anim_t

    def show_time(self, t_now: float) -> None:
        """Put every node where the state at time t_now puts it."""
        traj = self.traj
        if traj is None:
            return
        if traj.kind == "ah":
            for label, run, root in zip(traj.runs, traj.runs.values(), ("/ah/frame", "/ah/ghost")):
                k = min(int(np.searchsorted(run.t, t_now)), len(run.t) - 1)
                st = run.state
                node = self.frame if root == "/ah/frame" else self.ghost
                node.position = (float(st["x"][k]), float(st["y"][k]), 0.0)
                node.wxyz = geo.heading_wxyz(float(st["theta"][k]))
                parts = self._frame_parts[root]
                parts["spin"].wxyz = geo.spin_wxyz(float(st["phi"][k]))
                parts["load"].position = (0.0, 0.0, float(st["z"][k]))
                parts["thread"].points = geo.thread_local(traj.params, float(st["z"][k]))
            if self.client is not None and self.follow.value:
                k = min(int(np.searchsorted(traj.main.t, t_now)), len(traj.main.t) - 1)
                st = traj.main.state
                # look between the wheel and the bar, keep the viewer's own direction and zoom
                o = geo.wheel_centre_world(traj.params, float(st["theta"][k]), float(st["x"][k]), float(st["y"][k]))
                target = 0.5 * (o + np.array([st["x"][k], st["y"][k], 0.0]))
                # a fixed viewing direction at the chosen distance (untick to orbit freely)
                offset = np.array([-9.0, -15.0, 8.0]) / 19.2 * float(self.cam_dist.value)
                cam = self.client.camera
                cam.look_at = target
                cam.position = target + offset
        else:
            for run, particle in zip((traj.runs["M"], traj.runs["N"], traj.runs["DN"]), self.pt_particles):
                k = min(int(np.searchsorted(run.t, t_now)), len(run.t) - 1)
                particle.position = (float(run.state["x"][k]), 0.0, float(-run.state["y"][k]))
            if self.client is not None and self.follow.value:
                cam = self.client.camera
                cam.look_at = (0.0, 0.0, 0.0)
                cam.position = (0.0, -11.0 * float(self.cam_dist.value) / 19.0, 2.0)

    def tick(self, dt_wall: float, plots: bool) -> None:
        t_now = self.advance(dt_wall)
        self.show_time(t_now)
        if self.playing.value:
            self.scrub.value = round(t_now, 2)
        if plots and self.traj is not None:
            self._write_plots(self.traj, t_now)

    def close(self) -> None:
        if self.worker is not None:
            self.worker.close()


# --------------------------------------------------------------------------- app
class WebApp:
    """The viser server, one :class:`Session` per connected browser, one animation thread."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8080, simulate=core_simulate):
        self.server = viser.ViserServer(host=host, port=port, label="nmkane", verbose=False)
        self.server.gui.configure_theme(control_width="large", show_share_button=False)
        self.server.initial_camera.position = (-11.5, -15.0, 8.5)
        self.server.initial_camera.look_at = (-2.5, 0.0, 0.5)
        self.port = self.server.get_port()
        self.sessions: dict[int, Session] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._simulate = simulate
        self.frame_times: list[float] = []
        self.server.on_client_connect(self._connect)
        self.server.on_client_disconnect(self._disconnect)
        threading.Thread(target=_warm, daemon=True, name="nmkane-warm").start()
        self._anim = threading.Thread(target=self._animate, daemon=True, name="nmkane-animate")
        self._anim.start()

    def _connect(self, client: viser.ClientHandle) -> None:
        session = Session(client.gui, client.scene, client=client, simulate=self._simulate)
        with self._lock:
            self.sessions[client.client_id] = session

    def _disconnect(self, client: viser.ClientHandle) -> None:
        with self._lock:
            session = self.sessions.pop(client.client_id, None)
        if session is not None:
            session.close()

    def _animate(self) -> None:
        last, last_plot = time.perf_counter(), 0.0
        while not self._stop.is_set():
            t0 = time.perf_counter()
            dt_wall, last = t0 - last, t0
            plots = t0 - last_plot > 1.0 / PLOT_HZ
            if plots:
                last_plot = t0
            with self._lock:
                sessions = list(self.sessions.values())
            for s in sessions:
                try:
                    s.tick(dt_wall, plots)
                except Exception:       # a closed client mid-update: skip this frame
                    pass
            self.frame_times.append(t0)
            del self.frame_times[:-300]
            self._stop.wait(max(0.0, 1.0 / FPS - (time.perf_counter() - t0)))

    def fps(self) -> float:
        ts = self.frame_times[-60:]
        return (len(ts) - 1) / (ts[-1] - ts[0]) if len(ts) > 2 else 0.0

    def stop(self) -> None:
        self._stop.set()
        self._anim.join(2)
        with self._lock:
            sessions, self.sessions = list(self.sessions.values()), {}
        for s in sessions:
            s.close()
        self.server.stop()


def _warm() -> None:
    """Load the kernels (and the matrices text) before the first student asks."""
    for name, variants in (("appell-hamel", ("nonlinear", "linear")), ("sliding-particle", ("nonminimal", "minimal"))):
        for v in variants:
            try:
                get_system(name).kernel(v)
            except Exception:
                pass
    for name, v in (("appell-hamel", "nonlinear"), ("appell-hamel", "linear"), ("sliding-particle", "nonminimal")):
        try:
            matrices_markdown(name, v)      # symbolic work, once per process, before anyone waits
        except Exception:
            pass


def launch(host: str = "127.0.0.1", port: int = 8080) -> WebApp:
    """Start the web app in the background; returns a handle with ``.stop()`` and ``.port``."""
    return WebApp(host=host, port=port)


def main() -> None:
    stop = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.set())
    app = launch()
    print(f"nmkane 3D web app http://127.0.0.1:{app.port}/  (Ctrl-C to stop)", flush=True)
    while not stop.wait(0.5):
        pass
    app.stop()
