"""Keyboard shortcuts of the page, listed on it: space play/pause, ←/→ step, f fit view,
r reset view.  They are viser commands with hotkeys (``gui.add_command``: also in viser's
command palette, Ctrl/Cmd+K); viser does not fire them while a text box has the focus, so
typing a number with a minus or a space is never a shortcut."""

from __future__ import annotations

from collections.abc import Callable

STEP_FRAMES_S = 0.04  # ←/→ move the shown time by one 25-per-second frame of playback (× speed)
KEYS_TEXT = "**Keys:** space play/pause · ← / → step · f fit view · r reset view"


def step(session, direction: int) -> None:
    """Pause and show the time one frame (at the playback speed) earlier or later."""
    session.set_playing(False)
    session.seek(session.t_now + direction * STEP_FRAMES_S * float(session.speed.value))


def add_keys(gui, session) -> dict[str, object]:
    """The shortcuts' commands for one session (``session``: a :class:`web.session.MechanismApp`)
    and the line that lists them; returns the commands by key."""
    actions: dict[str, tuple[str, str, Callable[[], None]]] = {
        "space": ("Play / pause", "space", lambda: session.set_playing(not session.playing)),
        "left": ("Step back", "arrowleft", lambda: step(session, -1)),
        "right": ("Step forward", "arrowright", lambda: step(session, +1)),
        "f": ("Fit view (the mechanism now)", "F", lambda: session.fit()),
        "r": ("Reset view", "R", lambda: session.reset_view()),
    }
    out: dict[str, object] = {}
    for key, (label, hotkey, fn) in actions.items():
        cmd = gui.add_command(label, hotkey=hotkey)
        cmd.on_trigger(lambda _event, fn=fn: fn())
        out[key] = cmd
    gui.add_markdown(KEYS_TEXT)
    return out
