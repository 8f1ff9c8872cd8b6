"""Links that reopen a setup: the page's address carries the system and every control that
differs from its default, with the run settings' own names (those of the REST API)::

    /?system=NAME&dt=0.002&t_final=7&params.r=0.25&initial.u4=0.5&gamma=-10&compare=linear

:func:`link_pairs` writes them from the controls (numbers as they are typed, the variant
under the system's option name — ``model`` or ``formulation`` —, ``compare`` with ``gamma0``
for the run without stabilization); :func:`read_link` reads an address back into what to
set, and what to refuse with a reason (an unknown system or name, a value a box would
refuse).  ``scene=`` is read as ``system=`` (``nmkane serve --scene`` names it so).

:class:`LinkPanel` keeps one session's address up to date (through :mod:`web.page`), opens
the link the page was opened with, and copies it (a *Copy link* button).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from urllib.parse import parse_qsl

from .controls import Control
from .numbers import fmt

SYSTEM_KEYS = ("system", "scene")
CHOOSER_KEYS = ("model", "formulation", "integrator", "projection", "compare", "plot", "plot_x")
NUMBER_KEYS = ("dt", "t_final", "gamma", "gamma1", "gamma2")
PREFIXES = ("params.", "initial.")
OURS = (*SYSTEM_KEYS, *CHOOSER_KEYS, *NUMBER_KEYS)
ALIASES = {"Γ = 0": "gamma0"}  # a compare choice as it reads in a link
# the order of a link's parameters: times, parameters, initial values, gains, then the choices
ORDER = ("dt", "t_final", "params", "initial", "gamma", "gamma1", "gamma2", "variant", "integrator", "projection")
WAIT_FOR_PAGE_S = 5.0  # a page that has not said its address by then does not answer: write it anyway


def url_name(c: Control, option: str) -> str:
    """The name of a control in a link: its settings field, the variant under ``option``."""
    kind, _, name = c.field.partition(".")
    if kind == "variant":
        return option
    if kind == "option":
        return name
    return c.field


def url_value(c: Control, v) -> str:
    if c.kind == "number":
        return fmt(float(v))
    return ALIASES.get(str(v), str(v))


def _order(c: Control) -> int:
    kind = c.field.partition(".")[0]
    return ORDER.index(kind) if kind in ORDER else len(ORDER)


def link_pairs(system: str, option: str, values: dict[Control, object]) -> list[tuple[str, str]]:
    """The address's parameters for these control values: the system, then every control that
    differs from its default."""
    changed = [c for c in values if values[c] != c.default]
    return [("system", system)] + [(url_name(c, option), url_value(c, values[c])) for c in sorted(changed, key=_order)]


@dataclass
class Link:
    """What an address asks for: the system (None: the page's), values by Control, refusals."""

    system: str | None = None
    values: dict[Control, object] = field(default_factory=dict)
    refused: list[str] = field(default_factory=list)


def read_system(query: str, names) -> tuple[str | None, list[str]]:
    """The system an address names (None: none named) and the refusal of an unknown one."""
    for key, value in parse_qsl(query.lstrip("?"), keep_blank_values=True):
        if key in SYSTEM_KEYS:
            if value in names:
                return value, []
            return None, [f"link: {key}={value!r} is not a system here (choices: {', '.join(names)})"]
    return None, []


def read_link(query: str, controls: tuple[Control, ...], option: str) -> Link:
    """The values an address sets for these controls (a system's); numbers are returned as
    the text typed in the link (the boxes read and check them), choices checked here."""
    out = Link()
    by_name = {url_name(c, option): c for c in controls}
    for key, value in parse_qsl(query.lstrip("?"), keep_blank_values=True):
        if key in SYSTEM_KEYS:
            continue
        c = by_name.get(key)
        if c is None:
            if key in OURS or key.startswith(PREFIXES):
                out.refused.append(f"link: {key} is not a setting of this system (it has {', '.join(by_name)})")
            continue  # a parameter of viser's own (websocket, hideViserLogo, …)
        if c.kind in ("number", "text"):  # read by the box itself, as if typed
            out.values[c] = value
            continue
        choice = next((o for o in c.options if value in (o, ALIASES.get(o))), None)
        if choice is None:
            out.refused.append(f"link: {key}={value!r} is not one of {' | '.join(map(str, c.options))}")
        else:
            out.values[c] = choice
    return out


class LinkPanel:
    """The address of one session's page: written after every change once the page has said
    what it was opened with; that address opened first; a *Copy link* button.

    ``session`` is a :class:`web.session.MechanismApp` (its ``bridge``, ``open_link()`` and
    ``link_values()`` are used)."""

    def __init__(self, gui, session):
        self.session = session
        self.ready = False  # the page's own address has been read (or it does not answer)
        self.written: list[tuple[str, str]] | None = None
        self.opened_with: str | None = None
        self.copied: str | None = None
        self._asked_at: float | None = None
        self._lock = threading.Lock()
        self.button = gui.add_button("Copy link", hint="a link that reopens this page with these settings")
        self.note = gui.add_markdown("")
        self.button.on_click(lambda _: self.copy())

    def start(self) -> None:
        """Ask the page for its address (nothing to ask without a page: ready at once)."""
        import time

        self._asked_at = time.monotonic()
        if not self.session.bridge.ask_address():
            self.ready = True

    def on_answer(self, answer: dict) -> None:
        kind = answer.get("kind")
        if kind == "address":
            with self._lock:
                first = not self.ready
                self.ready = True
            search = str(answer.get("search", ""))
            if first:
                self.opened_with = search
                if search.strip("?"):
                    self.session.open_link(search)  # writes the address when it has applied it
                else:
                    self.update(force=True)
        elif kind == "copied":
            href = str(answer.get("href", ""))
            self.copied = href
            ok = bool(answer.get("ok"))
            self.note.content = ("Link copied: " if ok else "Copy this link: ") + f"`{href}`"

    def pairs(self) -> list[tuple[str, str]]:
        view = self.session.system_view
        return link_pairs(view.system, view.core.option, self.session.link_values())

    def update(self, force: bool = False) -> None:
        """Write the page's address when the settings changed (not before the page's own
        address has been read: it would overwrite the link the page was opened with)."""
        if not self.ready and self._asked_at is not None:
            import time

            self.ready = time.monotonic() - self._asked_at > WAIT_FOR_PAGE_S
        if not self.ready:
            return
        pairs = self.pairs()
        if pairs == self.written and not force:
            return
        self.written = pairs
        self.session.bridge.write_address(pairs, OURS, PREFIXES)

    def copy(self) -> None:
        self.update(force=True)
        if not self.session.bridge.copy_address():
            query = "&".join(f"{k}={v}" for k, v in self.pairs())
            self.note.content = f"Link to this setup: `/?{query}`"
