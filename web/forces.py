"""A system's declared forces at points (:mod:`nmkane_core.declare.forces`) on the page: arrows in
the scene, a plot of their magnitudes over time, and a readout at the time cursor.

:class:`ForceArrows` draws one arrow per declared force under ``<system node>/forces``: its
tail at the point where the force acts, along the force, ``scale`` metres per newton (the
declaration's ``Forces.scale``, else one chosen per run so that the largest force is about
the size of the system, rounded to 1, 2 or 5 × 10^k), with a label at its tip naming the
force and its magnitude (:mod:`web.labels` picks the corner of its text that covers no other
label); the scale ("arrows: 1 m = 20 N") is in the readout below the checkbox, not in the scene,
where it covered the labels at the contact point.  The points and world
vectors are computed once per run for every output row (the compiled geometry is
vectorized, the components are the run's ``point_forces``); a frame then only picks a row.
Each arrow is one unit arrow along its node's z, posed (position, wxyz) and stretched (z
scale) per frame: the page redraws a moved node at once, an arrow given new points it may not.

:func:`force_curves` is the plot's data (|R| of each force; compare runs dashed) and
:func:`readout` the text at the time cursor.  The page shows them where the system declares
forces; :attr:`ForceArrows.visible` is the "Show forces" switch (:class:`ForcePanel`, with the
readout, in the system's folder), on by default where the declaration says so (``Forces.show``).
"""

from __future__ import annotations

import math

import numpy as np

from nmkane_core.kernel.forces import compile_forces

from . import plots as pl
from .curves import run_suffix, style

COLORS = ((214, 39, 40), (31, 119, 180), (44, 160, 44), (148, 103, 189), (255, 127, 14))  # one per force
BIG = 1e6
TITLE = "Constraint forces |F| [N]"


def _variant(core, run) -> str:
    return run.settings.get(core.option) or core.default_variant


def nice_scale(largest: float, length: float) -> float:
    """Metres per newton so that a force of ``largest`` N is about ``length`` m: newtons per
    metre rounded up to 1, 2 or 5 × 10^k (a scale a reader can use)."""
    if not (largest > 0 and math.isfinite(largest)) or length <= 0:
        return 1.0
    per_m = largest / length
    e = math.floor(math.log10(per_m))
    for m in (1, 2, 5, 10):
        if m * 10**e >= per_m:
            return 1.0 / (m * 10**e)
    return 1.0 / (10 ** (e + 1))


UNIT = np.array([[[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]]], np.float32)  # every arrow: local z, scaled
HEAD = 0.2  # the head's share of an arrow's length


def _place(node, tail: np.ndarray, vec: np.ndarray) -> None:
    """An arrow node (the unit arrow along its z) from ``tail`` along ``vec``: its pose and its
    length as the node's z scale (the page redraws a moved or scaled node at once; new points
    of an arrow it may not)."""
    length = float(np.linalg.norm(vec))
    d = vec / length if length > 1e-12 else np.array([0.0, 0.0, 1.0])
    q = np.array([1.0 + d[2], -d[1], d[0], 0.0])  # wxyz turning z onto d
    n = float(np.linalg.norm(q))
    node.wxyz = tuple(q / n) if n > 1e-9 else (0.0, 1.0, 0.0, 0.0)  # d = −z: half a turn about x
    node.position = tuple(float(c) for c in tail)
    node.scale = (1.0, 1.0, max(length, 1e-6))


def _newtons(x: float) -> str:
    return f"{x:.3g} N" if abs(x) < 1e4 else f"{x:.3e} N"


class ForceArrows:
    """The arrows of one system's declared forces (one instance per system view and browser)."""

    def __init__(self, scene, core, parent: str):
        self.scene, self.core = scene, core
        self.compiled = {v: compile_forces(core, v) for v in core.variants}
        first = next((c for c in self.compiled.values() if c is not None), None)
        self.declared = first is not None
        self.names: list[str] = []
        for c in self.compiled.values():
            for f in c.forces if c is not None else ():
                if f["name"] not in self.names:
                    self.names.append(f["name"])
        self.default_visible = bool(first.show) if first is not None else False
        self.prefix = f"{parent}/forces"
        self.root = scene.add_frame(self.prefix, show_axes=False, visible=self.default_visible)
        self.arrows: dict = {}
        self.labels: dict = {}
        self.tails: dict[str, np.ndarray] = {}  # force name → (n, 3) points
        self.vectors: dict[str, np.ndarray] = {}  # force name → (n, 3) world force vectors, N
        self.scale = 1.0  # m per N
        self.width = 0.02
        self.shown: int | None = None

    @property
    def visible(self) -> bool:
        return bool(self.root.visible)

    @visible.setter
    def visible(self, on: bool) -> None:
        self.root.visible = bool(on) and self.declared

    def install(self, run, params: dict, extent: float = 0.5) -> None:
        """The points and vectors of every row of ``run`` (its variant's declared forces), the
        arrow scale, and the nodes (made on first use)."""
        self.shown = None
        self.tails, self.vectors = {}, {}
        compiled = self.compiled.get(_variant(self.core, run))
        if compiled is not None and run.point_forces:
            for name, (point, vec) in compiled.vectors(run.point_forces, run.state, params).items():
                self.tails[name] = np.clip(np.nan_to_num(point), -BIG, BIG)
                self.vectors[name] = np.clip(np.nan_to_num(vec), -BIG, BIG)
            largest = max(float(np.max(np.linalg.norm(v, axis=1), initial=0.0)) for v in self.vectors.values())
            self.scale = compiled.scale or nice_scale(largest, 1.2 * max(extent, 0.2))
            self.width = 0.04 * max(extent, 0.2)
            self._nodes()
        for name, node in self.arrows.items():
            node.visible = self.labels[name].visible = name in self.tails

    @property
    def scale_text(self) -> str:
        """The arrows' scale, for the readout."""
        return f"arrows: 1 m = {1 / self.scale:g} N" if self.tails else ""

    def _nodes(self) -> None:
        sc = self.scene
        for i, name in enumerate(self.names):
            if name in self.arrows:
                node = self.arrows[name]
                node.shaft_radius, node.head_radius = self.width, 2.2 * self.width
                continue
            self.arrows[name] = sc.add_arrows(
                f"{self.prefix}/{name}",
                points=UNIT,
                colors=COLORS[i % len(COLORS)],
                shaft_radius=self.width,
                head_radius=2.2 * self.width,
                head_length=HEAD,
            )
            self.labels[name] = sc.add_label(f"{self.prefix}/{name}_label", name, anchor="bottom-left")

    def pose(self, k: int) -> None:
        """The arrows at output row k (nothing is sent when row k is shown already)."""
        if k == self.shown or not self.tails:
            return
        self.shown = k
        for name, tail in self.tails.items():
            i = min(k, len(tail) - 1)
            _place(self.arrows[name], tail[i], self.scale * self.vectors[name][i])
            self.labels[name].position = tuple(float(c) for c in self._tip(name, i))

    def label_points(self, k: int) -> list:
        """The force labels shown at output row k, with their points (the arrows' tips)."""
        if not self.visible or not self.tails:
            return []
        return [(self.labels[name], self._tip(name, min(k, len(tail) - 1))) for name, tail in self.tails.items()]

    def _tip(self, name: str, i: int) -> np.ndarray:
        """The tip of force ``name``'s arrow at output row i (where its label is)."""
        return self.tails[name][i] + self.scale * self.vectors[name][i]

    def readout(self, k: int) -> None:
        """The labels' magnitudes at output row k (slow rate)."""
        for name, vec in self.vectors.items():
            i = min(k, len(vec) - 1)
            self.labels[name].text = f"{name} {_newtons(float(np.linalg.norm(vec[i])))}"


def force_curves(core, runs: dict, t: np.ndarray, on_t) -> pl.Curves | None:
    """The forces plot: |R| of each declared force of each run over ``t`` (the main run's
    times; ``on_t(run, values)`` puts another run's values on them), None when no run has any."""
    ys, labels, styles = [], [], []
    many = len(runs) > 1
    names: list[str] = []
    for r in runs.values():
        for col in r.point_forces:
            name = col.split(".", 1)[0]
            if name not in names:
                names.append(name)
    if not names:
        return None
    for j, (lab, r) in enumerate(runs.items()):
        compiled = compile_forces(core, _variant(core, r))
        if compiled is None or not r.point_forces:
            continue
        for name, mag in compiled.magnitudes(r.point_forces).items():
            ys.append(on_t(r, mag))
            labels.append(f"|{name}|{run_suffix(j, lab, many)}")
            styles.append(style(j, pl.COLORS[names.index(name) % len(pl.COLORS)]))
    if not ys:
        return None
    factor, unit = pl.readable(ys, "N")  # tick values neither "0 0 0" nor too long for the axis
    out = pl.curves(t, [y / factor for y in ys], labels, y_label=f"|F| [{unit}]")
    out.styles = styles
    return out


def readout(run, t_now: float) -> str:
    """The forces at the time cursor as one line of text: each force's magnitude and components."""
    if not run.point_forces:
        return ""
    k = int(np.clip(np.searchsorted(run.t, t_now, side="right") - 1, 0, len(run.t) - 1))
    groups: dict[str, list[tuple[str, float]]] = {}
    for col, v in run.point_forces.items():
        name, label = col.split(".", 1)
        groups.setdefault(name, []).append((label, float(v[k])))
    parts = []
    for name, comps in groups.items():
        mag = math.sqrt(sum(c * c for _, c in comps))
        detail = ", ".join(f"{lab} {val:.3g}" for lab, val in comps)
        parts.append(f"**{name}** {_newtons(mag)} ({detail})")
    return f"t = {float(run.t[k]):.3g} s — " + "; ".join(parts)


class ForcePanel:
    """The "Show forces" checkbox and the readout at the time cursor, in a view's folder."""

    def __init__(self, gui, arrows: ForceArrows):
        self.arrows = arrows
        self.box = gui.add_checkbox(
            "Show forces",
            initial_value=arrows.default_visible,
            hint="the declared constraint forces as arrows at their points (their scale below)",
        )
        self.text = gui.add_markdown("")
        self.box.on_update(lambda _: self.toggle())

    def toggle(self) -> None:
        self.arrows.visible = bool(self.box.value)

    def show(self, run, t_now: float) -> None:
        """The readout of ``run`` at ``t_now`` (and the arrows' scale)."""
        text = readout(run, t_now)
        scale = self.arrows.scale_text
        self.text.content = f"{text}  \n*{scale}*" if text and scale else text
