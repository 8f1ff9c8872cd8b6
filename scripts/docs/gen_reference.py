"""The API reference: one page per name of ``nmkane_core.__all__``.

Each name is mapped to the module that defines it by importing ``nmkane_core`` (module paths
inside the core change; the public names do not), and the page renders its docstring with
mkdocstrings (``::: nmkane_core.NAME``: griffe_nmkane.py makes the lazily bound names
visible to static analysis).
"""

from __future__ import annotations

import importlib
import inspect

from _md import cell


def _summary(obj: object) -> str:
    doc = inspect.getdoc(obj) or ""
    first = doc.strip().split("\n\n", 1)[0].replace("\n", " ")
    return first


def pages() -> dict[str, str]:
    core = importlib.import_module("nmkane_core")
    out: dict[str, str] = {}
    rows, nav = [], ["* [Overview](index.md)"]
    for name in core.__all__:
        obj = getattr(core, name)
        kind = "class" if inspect.isclass(obj) else "function"
        out[f"reference/{name}.md"] = (
            f"# {name}\n\n"
            f"`from nmkane_core import {name}` — a {kind}, defined today in `{obj.__module__}` "
            "(import it from `nmkane_core`: that name is the stable one).\n\n"
            f"::: nmkane_core.{name}\n"
        )
        rows.append(f"| [`{name}`]({name}.md) | {kind} | {cell(_summary(obj))} |")
        nav.append(f"* [{name}]({name}.md)")
    out["reference/index.md"] = (
        "# API reference\n\n"
        "Every public name of the library, `nmkane_core.__all__`, in the order the package lists\n"
        "them; each has its page, rendered from its docstring when this site is built.  Import\n"
        "them from `nmkane_core` (`from nmkane_core import simulate`): the modules that define\n"
        "them are the library's business and may move.\n\n"
        "| name | kind | summary |\n|---|---|---|\n" + "\n".join(rows) + "\n"
    )
    out["reference/SUMMARY.md"] = "\n".join(nav) + "\n"
    return out
