"""One code path for every system: nothing in ``web/`` names a system.

What a system looks like, its defaults and its comparisons are declared with the system
(:mod:`nmkane_core.declare.visuals`, ``System.showcase``); the web app only renders declarations.
This check is mechanical: no source file of the web package (code, comments or docstrings)
contains the name of a built-in system or a word of one."""

import re
from pathlib import Path

from nmkane_core.systems import BUILTIN

WEB = Path(__file__).resolve().parents[2] / "web"
GENERIC_WORDS = {"edge", "disk", "rolling"}  # words of system names that are ordinary English in code


def _forbidden() -> set[str]:
    words = set(BUILTIN)
    for name in BUILTIN:
        words |= {w for w in name.split("-") if len(w) > 3 and w not in GENERIC_WORDS}
    return words | {"appell", "hamel", "bicycle", "particle", "sleigh", "mechanism scene"}


def test_web_names_no_system():
    words = _forbidden()
    assert {"appell-hamel", "appell", "particle", "bicycle", "whipple"} <= words
    found = []
    for path in sorted(WEB.glob("*.py")):
        text = path.read_text(encoding="utf-8").lower()
        for w in sorted(words):
            for m in re.finditer(re.escape(w), text):
                line = text.count("\n", 0, m.start()) + 1
                found.append(f"{path.name}:{line}: {w!r}")
    assert not found, "web/ names systems:\n" + "\n".join(found)
