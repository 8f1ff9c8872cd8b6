"""Plug-in systems: Python files or modules that register systems when imported.

Three ways in, all loaded by the same function:

* ``--systems PATH_OR_MODULE`` (repeatable) on ``nmkane run``, ``nmkane matrices`` and
  ``nmkane serve``;
* the environment variable ``NMKANE_SYSTEMS``: entries separated by ``os.pathsep``;
* the entry-point group ``nmkane.systems`` of installed packages: each entry names a
  module (imported) or a function (called) that registers systems.

A systems file is ordinary Python that calls :func:`nmkane_core.register`: it runs with the
rights of the process that loads it (the service's, for ``nmkane serve``) — load only files
you trust.  A file that fails to import or to register — any exception, or ``sys.exit()``
while it loads — is reported in one line naming the file and the error, and the others load
all the same (``--systems``: the command's error, exit code 2).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
import threading
from dataclasses import dataclass
from importlib.metadata import entry_points
from pathlib import Path

__all__ = ["ENTRY_POINT_GROUP", "ENV_VAR", "PluginError", "load_systems", "load_default_plugins", "loaded_specs"]

ENTRY_POINT_GROUP = "nmkane.systems"
ENV_VAR = "NMKANE_SYSTEMS"

_LOADED: dict[str, object] = {}
_LOCK = threading.RLock()
_defaults_loaded = False


@dataclass(frozen=True)
class PluginError:
    """A systems file or module that could not be loaded: where, and why (one line)."""

    source: str
    error: str

    def __str__(self) -> str:
        return f"nmkane: systems from {self.source} not loaded: {self.error}"


def _one_line(e: BaseException) -> str:
    if isinstance(e, SystemExit):  # sys.exit(3), exit(): would end the whole command, silently
        return f"SystemExit: it called sys.exit({e.code!r}) while loading"
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def _import_path(path: Path) -> object:
    digest = hashlib.sha256(str(path.resolve()).encode()).hexdigest()[:12]
    name = f"nmkane_user_systems_{path.stem}_{digest}"
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def _load_one(spec: str) -> object:
    spec = spec.strip()
    path = Path(spec).expanduser()
    if spec.endswith(".py") or os.sep in spec or path.exists():
        if not path.is_file():
            raise FileNotFoundError(f"no such file: {path}")
        return _import_path(path)
    return importlib.import_module(spec)


def load_systems(specs, *, strict: bool = False) -> list[PluginError]:
    """Import systems files (paths ending in ``.py``) or modules (dotted names).

    Each is imported once per process.  Returns the failures (one :class:`PluginError`
    each); with ``strict`` the first failure is raised as an
    :class:`~nmkane_core.errors.InputError` instead."""
    from ..errors import InputError

    errors = []
    for spec in specs:
        if not spec or not str(spec).strip():
            continue
        key = str(Path(spec).expanduser().resolve()) if str(spec).endswith(".py") else str(spec)
        with _LOCK:
            if key in _LOADED:
                continue
            try:
                _LOADED[key] = _load_one(str(spec))
            except (Exception, SystemExit) as e:  # not KeyboardInterrupt: Ctrl-C still stops
                err = PluginError(str(spec), _one_line(e))
                if strict:
                    raise InputError(
                        "systems",
                        str(spec),
                        "a systems file or module that imports and registers its systems",
                        err.error,
                    ) from None
                errors.append(err)
    return errors


def loaded_specs() -> list[str]:
    """The systems files and modules loaded in this process (to hand to a child process,
    e.g. through ``NMKANE_SYSTEMS``)."""
    with _LOCK:
        return list(_LOADED)


def _from_entry_points() -> list[PluginError]:
    errors = []
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        try:
            obj = ep.load()
            if callable(obj):
                obj()
        except (Exception, SystemExit) as e:
            errors.append(PluginError(f"entry point {ep.name} ({ep.value})", _one_line(e)))
    return errors


def load_default_plugins() -> list[PluginError]:
    """Once per process: the ``nmkane.systems`` entry points and ``$NMKANE_SYSTEMS``.
    Failures are printed to stderr (one line each) and do not stop the others."""
    global _defaults_loaded
    with _LOCK:
        if _defaults_loaded:
            return []
        _defaults_loaded = True
    errors = _from_entry_points()
    env = os.environ.get(ENV_VAR, "")
    errors += load_systems([s for s in env.split(os.pathsep) if s.strip()])
    for e in errors:
        print(e, file=sys.stderr)
    return errors
