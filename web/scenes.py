"""One page's scene switching: which system is shown, and its controls.

:class:`Scenes` holds the *Scene* dropdown and one :class:`~web.generic.GenericView` per
system chosen so far (its scene, its simulation folder — controls, parameters, reset button —
and its plots, built when it is first chosen; the chosen one visible), finds the shown
system's controls by their field, puts them back to the system's defaults, and opens the
page a link asks for (system, then values).
"""

from __future__ import annotations

import viser

from . import stability
from .controls import Control
from .forces import ForcePanel
from .generic import GenericView
from .link import Link, read_link, read_system
from .numbers import ExpressionField, NumberField


class Scenes:
    """The systems of one session (``session``: a :class:`web.session.MechanismApp`, whose
    ``gui``, ``scene``, ``controls``, ``plots``, ``plots_folder``, ``lock``, ``runner``,
    ``playback`` and ``request()`` it uses).  ``choices``: dropdown title -> system name."""

    def __init__(self, session, choices: dict[str, str]):
        self.session = session
        self.choices = choices
        self.views: dict[str, GenericView] = {}
        self.sim_controls: dict[str, dict] = {}  # kind -> {Control: handle}
        self.folders: dict[str, viser.GuiFolderHandle] = {}
        self.legends: dict[str, viser.GuiMarkdownHandle] = {}
        self.resets: dict[str, viser.GuiButtonHandle] = {}

    def add_dropdown(self, first: str) -> None:
        """The *Scene* dropdown, ``first`` (a title) chosen."""
        self.scene_choice = self.session.gui.add_dropdown("Scene", options=tuple(self.choices), initial_value=first)

    def add_first(self, first: str) -> None:
        """The first system's view and its folder (shown)."""
        view = GenericView(self.session.scene, self.choices[first])
        self.views[view.kind] = self.system_view = view  # the chosen system's view
        self.add_view_gui(view, visible=True)

    def wire(self) -> None:
        self.scene_choice.on_update(lambda _: self.on_scene())

    @property
    def kind(self) -> str:
        return self.system_view.kind

    # ---------------------------------------------------------------- a system's folder
    def add_view_gui(self, view, visible: bool, order: float | None = None) -> None:
        """A view's simulation folder (controls, parameters, reset button), wired to re-simulate."""
        s = self.session
        gui, controls = s.gui, s.controls
        self.folders[view.kind] = folder = controls.form(view.folder, visible=visible, order=order)
        with folder:
            core = view.core
            text = [f"*{core.description}*"] if core.description else []
            text += [f"**What to try:** {core.what_to_try}"] if core.what_to_try else []
            if text:
                gui.add_markdown("  \n".join(text))
            handles: dict[Control, object] = {}
            for c in view.controls:
                if c.field.startswith("initial.") and not any(k.field.startswith("initial.") for k in handles):
                    gui.add_markdown("**Initial values** (t = 0; the dependent ones follow from the constraints)")
                handles[c] = controls.add(c)
                if c.field == "option.compare":
                    self.legends[view.kind] = gui.add_markdown("")  # which colour is which run
            if view.forces.declared:
                view.force_panel = ForcePanel(gui, view.forces)
            with gui.add_folder(view.params_folder, expand_by_default=False):
                params = {c.attr: controls.add(c) for c in view.param_controls}
            self.resets[view.kind] = gui.add_button(view.reset_label)
        handles.update({c: params[c.attr] for c in view.param_controls})
        self.sim_controls[view.kind] = handles
        self.keep_the_ghost(handles)
        for h in handles.values():
            controls.on_change(h, s.request)
        self.resets[view.kind].on_click(lambda _: self.reset_to_paper())

    def keep_the_ghost(self, handles: dict) -> None:
        """Choosing as the model the one shown as the ghost swaps them: the ghost then shows
        the model shown before (rather than silently vanishing)."""
        by_field = {c.field: h for c, h in handles.items()}
        variant, compare = by_field.get("variant"), by_field.get("option.compare")
        if variant is None or compare is None:
            return
        before = {"variant": variant.value}

        def swap(_event) -> None:
            new, old = variant.value, before["variant"]
            before["variant"] = new
            if compare.value == new and old != new:
                self.session.controls.set_quietly(compare, old)

        variant.on_update(swap)  # before the re-simulation's callback: the run sees the swapped compare

    def view_for(self, title: str) -> GenericView:
        """The view of a dropdown entry (built on first use)."""
        s = self.session
        kind = self.choices[title]
        if kind not in self.views:
            view = GenericView(s.scene, kind)
            self.views[kind] = view
            first = next(iter(self.folders.values()))
            self.add_view_gui(view, visible=False, order=getattr(first, "order", None))
            with s.plots_folder:
                s.plots.add_view(s.gui, view)
                stability.attach(s, view)  # eigenvalue plot of a declared stability sweep
        return self.views[kind]

    # ---------------------------------------------------------------- switching
    def on_scene(self) -> None:
        """The dropdown's system shown: its scene, folder and plots; its speed; its first view;
        a run."""
        s = self.session
        with s.lock:
            self.system_view = self.view_for(self.scene_choice.value)
        for kind, folder in self.folders.items():
            folder.visible = kind == self.kind
        for v in self.views.values():
            v.root.visible = v is self.system_view
        s.plots.show_kind(self.kind)
        s.playback.speed.value = self.system_view.speed
        s.playback.look(follow=None)
        s.request()

    def control(self, field: str):
        """The shown system's control handle for a settings field (``"gamma"``, ``"variant"``,
        ``"params.m"``, ``"initial.u1"``, ``"option.compare"``, ...); KeyError if it has none."""
        for c, h in self.sim_controls[self.kind].items():
            if c.field == field:
                return h
        raise KeyError(f"{self.system_view.system} has no control for {field!r}")

    def reset_to_paper(self) -> None:
        """Every control of the current scene back to its default (the system's showcase, e.g. the
        paper's values, where it declares one): one re-simulation."""
        runner = self.session.runner
        runner.quiet = True
        try:
            for c, h in self.sim_controls[self.kind].items():
                h.value = c.default
        finally:
            runner.quiet = False
        self.session.request()

    # ---------------------------------------------------------------- links
    def link_values(self) -> dict:
        """The shown system's controls and their values (what a link carries)."""
        value = self.session.controls.value
        return {c: value(h) for c, h in self.sim_controls[self.kind].items()}

    def open_link(self, query: str) -> Link:
        """Build the page a link asks for (``?system=…&dt=…``): its system, then its values —
        each box reads its value as if it were typed, a bad one is refused beside its box and
        the rest are applied — and one run."""
        s = self.session
        system, refused = read_system(query, tuple(self.choices.values()))
        s.runner.quiet = True
        try:
            if system is not None and system != self.kind:
                self.scene_choice.value = next(t for t, n in self.choices.items() if n == system)
            link = read_link(query, tuple(self.sim_controls[self.kind]), self.system_view.core.option)
            handles = self.sim_controls[self.kind]
            for c, v in link.values.items():
                if isinstance(handles[c], (NumberField, ExpressionField)):
                    handles[c].text.value = str(v)  # read and checked as typed (at once: set from Python)
                else:
                    handles[c].value = v
        finally:
            s.runner.quiet = False
        s.controls.note("link", refused + link.refused)
        s.request(keep_notes=True)
        return link
