"""The systems users choose by name: built-in ones and those registered in this process.

``register(name)`` registers a zero-argument factory of a :class:`~nmkane_core.system.System`;
``get_system(name)`` builds it once and returns it.  The built-in systems
(:data:`nmkane_core.systems.BUILTIN`) are registered on first use.
"""

from __future__ import annotations

import threading
from typing import Callable

from .errors import InputError
from .system import System

__all__ = ["register", "unregister", "get_system", "system_names"]

_FACTORIES: dict[str, Callable[[], System]] = {}
_BUILT: dict[str, System] = {}
_LOCK = threading.RLock()
_builtin_loaded = False


def register(name: str):
    """Decorator: register a zero-argument factory of a :class:`System` under ``name``."""
    def deco(factory):
        with _LOCK:
            _FACTORIES[name] = factory
            _BUILT.pop(name, None)
        return factory
    return deco


def unregister(name: str) -> None:
    """Forget a registered system (no error if it is not registered)."""
    with _LOCK:
        _FACTORIES.pop(name, None)
        _BUILT.pop(name, None)


def _load_builtin() -> None:
    global _builtin_loaded
    if _builtin_loaded:
        return
    from .systems import BUILTIN

    with _LOCK:
        for name, factory in BUILTIN.items():
            _FACTORIES.setdefault(name, factory)
        _builtin_loaded = True


def system_names() -> tuple[str, ...]:
    _load_builtin()
    return tuple(_FACTORIES)


def get_system(name: str, field_path: str = "system") -> System:
    _load_builtin()
    with _LOCK:
        if name not in _FACTORIES:
            raise InputError(field_path, name, " | ".join(_FACTORIES), "unknown system")
        if name not in _BUILT:
            _BUILT[name] = _FACTORIES[name]()
        return _BUILT[name]
