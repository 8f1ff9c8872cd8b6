"""The scene graphs: geometry built once per parameter set, poses set per frame.

Scene tree (one per browser)::

    /mechanism                       the Appell–Hamel scene (hidden for the particle)
    /mechanism/ground                the x–y plane, a grid that follows in 5 m steps
    /mechanism/trace                 P's intercept on the plane (the paper's Fig. 7)
    /mechanism/body                  pose: P's (x, y) on the plane, heading θ about z
    /mechanism/body/frame/...        beam, fork, legs, P's bar, pulleys, hole in the plane
    /mechanism/body/wheel            the wheel centre o, ρ behind P, at height a
    /mechanism/body/wheel/spin       the spin φ about the axle (disk, stripe, drum)
    /mechanism/body/load             the load P at height z on the bar
    /mechanism/body/thread, hanging  the thread (fixed run over the pulleys, hanging run)
    /mechanism/ghost/...             the other constraint model, translucent (compare)
    /particle/lane{0,1,2}/...        bowl, particle and label: M | N | DN

Each animation frame sets one pose per moving part: body (position, heading), spin,
load, hanging thread.  Geometry comes from :mod:`web.geometry`.
"""

from __future__ import annotations

import numpy as np

from . import geometry as geo

FRAME_COLOR = (150, 160, 178)
WHEEL_COLOR = (48, 88, 196)
DRUM_COLOR = (226, 178, 40)
PULLEY_COLOR = (200, 140, 40)
LOAD_COLOR = (36, 160, 72)
THREAD_COLOR = (120, 30, 20)
TRACE_COLOR = (214, 48, 39)
GHOST_COLOR = (240, 120, 30)
GRID_STEP = 5.0


class _Body:
    """Everything that rides on the frame: one pose per moving part."""

    def __init__(self, scene, root: str, *, ghost: bool):
        self.scene, self.root, self.ghost = scene, root, ghost
        self.node = scene.add_frame(root, show_axes=False, visible=not ghost)
        self.layout: geo.Layout | None = None
        self.bottom = None
        self.spin = self.load = self.hanging = None

    def _color(self, c):
        return GHOST_COLOR if self.ghost else c

    def _member(self, name: str, p, q, thickness: float = geo.MEMBER, color=FRAME_COLOR):
        p, q = np.asarray(p, float), np.asarray(q, float)
        length = float(np.linalg.norm(q - p))
        return self.scene.add_box(
            f"{self.root}/frame/{name}",
            color=self._color(color),
            dimensions=(thickness, thickness, max(length, 1e-3)),
            position=tuple((p + q) / 2),
            wxyz=geo.quat_z_to(q - p),
            opacity=0.3 if self.ghost else None,
            cast_shadow=not self.ghost,
        )

    def shape(self, layout: geo.Layout, bottom: float) -> None:
        """(Re)build the parts for these sizes; P's bar reaches down to ``bottom``."""
        sc, r, L = self.scene, self.root, layout
        op = 0.3 if self.ghost else None
        if layout != self.layout:
            sc.add_frame(f"{r}/frame", show_axes=False)
            for name, (p, q) in L.members(bottom).items():
                if name != "bar" and (not self.ghost or name == "axle"):
                    self._member(name, p, q, 0.06 if name == "axle" else geo.MEMBER)
            if not self.ghost:
                for i, foot in enumerate(L.feet()):  # skids on the plane
                    sc.add_box(
                        f"{r}/frame/foot{i}",
                        color=FRAME_COLOR,
                        dimensions=(1.2, 0.3, 0.08),
                        position=tuple(foot + np.array([0.0, 0.0, 0.04])),
                    )
                for i, c in enumerate(L.pulleys):
                    sc.add_cylinder(
                        f"{r}/frame/pulley{i + 1}",
                        radius=L.b,
                        height=0.12,
                        color=PULLEY_COLOR,
                        wxyz=geo.AXIS_Z_TO_Y,
                        position=c,
                    )
                sc.add_cylinder(
                    f"{r}/frame/hole",
                    radius=0.5,
                    height=0.02,
                    color=(45, 40, 35),
                    position=(0.0, geo.BAR_OFFSET / 2, 0.012),
                    opacity=0.75,
                    cast_shadow=False,
                )
            sc.add_frame(f"{r}/wheel", show_axes=False, position=L.wheel_centre)
            self.spin = sc.add_frame(f"{r}/wheel/spin", show_axes=False)
            sc.add_cylinder(
                f"{r}/wheel/spin/disk",
                radius=L.a,
                height=L.wheel_width,
                color=self._color(WHEEL_COLOR),
                wxyz=geo.AXIS_Z_TO_Y,
                opacity=op,
                radial_segments=48,
            )
            sc.add_box(
                f"{r}/wheel/spin/stripe",
                color=(245, 245, 245) if not self.ghost else GHOST_COLOR,
                dimensions=(0.92 * L.a, L.wheel_width + 0.02, 0.12 * L.a),
                position=(0.46 * L.a, 0.0, 0.0),
                opacity=op,
            )
            sc.add_cylinder(
                f"{r}/wheel/spin/drum",
                radius=L.b,
                height=L.drum_length,
                color=self._color(DRUM_COLOR),
                wxyz=geo.AXIS_Z_TO_Y,
                position=(0.0, L.drum_y, 0.0),
                opacity=op,
            )
            sc.add_box(
                f"{r}/wheel/spin/drum_stripe",
                color=(120, 80, 10) if not self.ghost else GHOST_COLOR,
                dimensions=(0.9 * L.b, L.drum_length + 0.02, 0.1 * L.b),
                position=(0.45 * L.b, L.drum_y, 0.0),
                opacity=op,
            )
            self.load = sc.add_icosphere(
                f"{r}/load",
                radius=geo.LOAD_RADIUS,
                color=self._color(LOAD_COLOR),
                opacity=op,
                position=(0.0, 0.0, L.z0),
            )
            if not self.ghost:
                sc.add_label(f"{r}/load/label", "P", position=(0.45, 0.0, 0.45), anchor="bottom-left")
            sc.add_line_segments(
                f"{r}/thread",
                points=geo.segments(L.thread_fixed()),
                colors=self._color(THREAD_COLOR),
                thickness=2.0,
                thickness_units="screen",
            )
            self.hanging = sc.add_line_segments(
                f"{r}/hanging",
                points=L.hanging(L.z0),
                colors=self._color(THREAD_COLOR),
                thickness=2.0,
                thickness_units="screen",
            )
            self.layout = layout
            self.bottom = None
        if bottom != self.bottom:
            p, q = L.members(bottom)["bar"]
            self._member("bar", p, q)
            self.bottom = bottom

    def pose(self, theta: float, phi: float, x: float, y: float, z: float) -> None:
        self.node.position = (x, y, 0.0)
        self.node.wxyz = geo.heading_wxyz(theta)
        self.spin.wxyz = geo.spin_wxyz(phi)
        self.load.position = (0.0, 0.0, z)
        self.hanging.points = self.layout.hanging(z)


class MechanismScene:
    """The Appell–Hamel mechanism (and its compare ghost) in one viser scene."""

    ROOT = "/mechanism"

    def __init__(self, scene, params: dict):
        self.scene = scene
        self.root = scene.add_frame(self.ROOT, show_axes=False)
        self.ground = scene.add_grid(
            f"{self.ROOT}/ground",
            width=600.0,
            height=600.0,
            plane="xy",
            cell_size=1.0,
            section_size=GRID_STEP,
            cell_color=(205, 208, 200),
            section_color=(150, 155, 145),
            infinite_grid=True,
            fade_distance=260.0,
            plane_color=(232, 236, 226),
            plane_opacity=0.6,
            shadow_opacity=0.25,
        )
        self.trace = scene.add_line_segments(
            f"{self.ROOT}/trace",
            points=np.zeros((1, 2, 3), np.float32),
            colors=TRACE_COLOR,
            thickness=3.0,
            thickness_units="screen",
        )
        self.body = _Body(scene, f"{self.ROOT}/body", ghost=False)
        self.ghost = _Body(scene, f"{self.ROOT}/ghost", ghost=True)
        self.shape(params, float(params["z0"]))

    @property
    def layout(self) -> geo.Layout:
        return self.body.layout

    def shape(self, params: dict, z_min: float) -> None:
        layout = geo.Layout.of(params)
        bottom = geo.pit_bottom(z_min)
        if self.body.bottom is not None and layout == self.body.layout and bottom <= self.body.bottom <= bottom + 20.0:
            bottom = self.body.bottom  # deep enough already: keep the bar
        for b in (self.body, self.ghost):
            b.shape(layout, bottom)

    def set_trace(self, x: np.ndarray, y: np.ndarray) -> None:
        self.trace.points = geo.trace_segments(x, y)

    def show_ghost(self, visible: bool) -> None:
        self.ghost.node.visible = visible

    def pose(self, row: dict, ghost_row: dict | None = None) -> None:
        """Put the parts where the state row (theta, phi, x, y, z) puts them."""
        self.body.pose(row["theta"], row["phi"], row["x"], row["y"], row["z"])
        if ghost_row is not None:
            self.ghost.pose(ghost_row["theta"], ghost_row["phi"], ghost_row["x"], ghost_row["y"], ghost_row["z"])
        # the grid follows in whole sections (it looks fixed to the plane)
        gx = round(row["x"] / GRID_STEP) * GRID_STEP
        gy = round(row["y"] / GRID_STEP) * GRID_STEP
        self.ground.position = (float(np.clip(gx, -1e7, 1e7)), float(np.clip(gy, -1e7, 1e7)), 0.0)

    def targets(self, row: dict) -> dict[str, np.ndarray]:
        return mechanism_targets(self.layout, row)


def mechanism_targets(layout: geo.Layout, row: dict) -> dict[str, np.ndarray]:
    """Camera targets in world coordinates at a state: the whole mechanism (between wheel and
    bar, 0.4 of the way up), the wheel centre and the load."""
    th, x, y, z = row["theta"], row["x"], row["y"], row["z"]
    o = geo.wheel_centre_world({"rho": layout.rho, "a": layout.a}, th, x, y)
    mid = 0.5 * (o + np.array([x, y, 0.0]))
    mid[2] = 0.4 * layout.h
    return {"mechanism": mid, "wheel": o, "load": np.array([x, y, z])}


LANES = (
    ("M", "M · minimal (137)", (40, 110, 215)),
    ("N", "N · nonminimal, Γ1 = Γ2 = 0", (220, 80, 35)),
    ("DN", "DN · nonminimal, damped", (30, 160, 75)),
)


class ParticleScene:
    """Example 2: the bowl ψ = 0 three times, with the M, N and DN solutions."""

    ROOT = "/particle"
    SPACING = 4.0

    def __init__(self, scene, l0: float = 1.0, half_width: float = 1.6):
        self.scene = scene
        self.root = scene.add_frame(self.ROOT, show_axes=False, visible=False)
        self.balls, self.labels = [], []
        for i, (_, title, color) in enumerate(LANES):
            lane = f"{self.ROOT}/lane{i}"
            scene.add_frame(lane, show_axes=False, position=(self.SPACING * (i - 1), 0.0, 0.0))
            scene.add_label(f"{lane}/title", title, position=(0.0, 0.0, 1.35), anchor="bottom-center")
            self.labels.append(scene.add_label(f"{lane}/readout", "", position=(0.0, 0.0, 1.3), anchor="top-center"))
            self.balls.append(scene.add_icosphere(f"{lane}/particle", radius=0.09, color=color))
        self.shaped_for = None
        self.shape(l0, half_width)

    def shape(self, l0: float, half_width: float) -> None:
        if self.shaped_for == (l0, half_width):
            return
        verts, faces = geo.particle_bowl(l0, half_width)
        for i in range(len(LANES)):
            self.scene.add_mesh_simple(
                f"{self.ROOT}/lane{i}/bowl",
                verts,
                faces,
                color=(175, 188, 205),
                opacity=0.65,
                side="double",
                cast_shadow=False,
            )
        self.shaped_for = (l0, half_width)

    def pose(self, rows: list[dict]) -> None:
        for ball, row in zip(self.balls, rows, strict=True):
            ball.position = geo.particle_position(row["x"], row["y"])

    def readouts(self, texts: list[str]) -> None:
        for label, text in zip(self.labels, texts, strict=True):
            label.text = text
