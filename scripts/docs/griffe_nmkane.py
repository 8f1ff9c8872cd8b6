"""Griffe extension for nmkane's docs build (mkdocstrings reads the sources statically).

Two jobs:

* ``nmkane_core`` binds some public names lazily (PEP 562 ``__getattr__``, so that ``import
  nmkane_core`` does not import sympy): static analysis does not see them.  The extension
  imports ``nmkane_core`` and adds an alias for every name of ``nmkane_core.__all__`` to the
  module that defines it, so ``::: nmkane_core.Derivation`` and cross-references
  ``[Derivation][nmkane_core.Derivation]`` work whatever module the name lives in today.
* Docstrings not yet converted to Markdown still carry Sphinx roles (``:class:`X```).
  mkdocstrings does not render them; the extension rewrites each into an autorefs
  cross-reference when it names a public object (``[X][nmkane_core.X]``) and into code
  otherwise, so a page never shows a raw role.  ``NMKANE_DOCS_ROLES=error`` makes any role
  left in a rendered docstring a build failure (the goal once every docstring is converted).
"""

from __future__ import annotations

import importlib
import logging
import os
import re
from typing import Any

import griffe

LOG = logging.getLogger("mkdocs.plugins.nmkane")
ROLE = re.compile(r":(?:py:)?(class|func|meth|mod|data|attr|exc|obj):`(~?)([^`<>]+?)`")


def public_names() -> dict[str, str]:
    """Each name of ``nmkane_core.__all__`` → the dotted path of the object it is bound to."""
    core = importlib.import_module("nmkane_core")
    out = {}
    for name in core.__all__:
        obj = getattr(core, name)
        module = getattr(obj, "__module__", None)
        if not module:
            raise RuntimeError(f"nmkane_core.{name}: no __module__, cannot find where it is defined")
        out[name] = f"{module}.{getattr(obj, '__qualname__', name)}"
    return out


class LazyPublicNames(griffe.Extension):
    """Alias every public name into ``nmkane_core`` (see the module docstring)."""

    def __init__(self) -> None:
        self.targets = public_names()

    def on_package(self, *, pkg: griffe.Module, loader: griffe.GriffeLoader, **kwargs: Any) -> None:
        if pkg.path != "nmkane_core":
            return
        for name, target in self.targets.items():
            if name not in pkg.members:
                pkg.set_member(name, griffe.Alias(name, target, parent=pkg))


class SphinxRoles(griffe.Extension):
    """Rewrite Sphinx roles into autorefs links (public names) or code (see the module docstring)."""

    def __init__(self) -> None:
        self.public = {path: f"nmkane_core.{name}" for name, path in public_names().items()}
        self.public.update({f"nmkane_core.{name}": f"nmkane_core.{name}" for name in public_names()})
        self.strict = os.environ.get("NMKANE_DOCS_ROLES") == "error"

    def _target(self, path: str, context: griffe.Object) -> str | None:
        candidates = [path, f"nmkane_core.{path}"]
        module = context.module.path if not context.is_module else context.path
        candidates += [f"{module}.{path}", f"{module.rpartition('.')[0]}.{path.lstrip('.')}"]
        for c in candidates:
            if c in self.public:
                return self.public[c]
        return None

    def on_object(self, *, obj: griffe.Object, loader: griffe.GriffeLoader, **kwargs: Any) -> None:
        if obj.is_alias or obj.docstring is None or ":" not in obj.docstring.value:
            return
        text = obj.docstring.value

        def replace(m: re.Match) -> str:
            _role, tilde, path = m.groups()
            shown = path.rpartition(".")[2] if tilde else path
            if self.strict:
                LOG.warning("%s: Sphinx role %s left in the docstring", obj.path, m.group(0))
            target = self._target(path, obj)
            return f"[`{shown}`][{target}]" if target else f"`{shown}`"

        obj.docstring.value = ROLE.sub(replace, text)
