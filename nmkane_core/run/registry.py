"""The systems users choose by name: built-in ones, plugged-in ones and those registered in
this process.

``register(system)`` checks a :class:`~nmkane_core.declare.system.System` against its models
(:func:`check_system`: parameter names, the default initial state) and makes it available
by its name to :func:`get_system`, the CLI, the REST service and the web app.  Registering
a name again replaces the earlier system (with a warning if that one was already used).
The built-in systems (:data:`nmkane_core.systems.BUILTIN`) are registered on first use,
together with plug-ins (:mod:`nmkane_core.run.plugins`).
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable
from typing import overload

from ..declare.system import System
from ..errors import InputError
from ..kernel.built import built
from .initial import default_state
from .partition import check_rank

__all__ = ["register", "unregister", "get_system", "system_names", "generation", "check_system"]

_FACTORIES: dict[str, Callable[[], System]] = {}
_BUILT: dict[str, System] = {}
_USED: set[str] = set()
_LOCK = threading.RLock()
_builtin_loaded = False  # the load has started
_builtin_ready = False  # the load has finished
_generation = 0  # counts changes, so that caches of the catalogue know when to refresh


def check_system(system: System, variants: tuple[str, ...] | None = None) -> None:
    """Check a declaration against its models; raise :class:`InputError` saying what to change.

    Each checked variant builds and derives (or loads from the cache); its parameter symbols
    must be exactly the declared parameters; the default initial state must name only state
    values and be consistent with the constraints (independent values are completed:
    :func:`~nmkane_core.run.initial.default_state`); the constraints' rank there must leave as
    many independent speeds as a declared partition has
    (:func:`~nmkane_core.run.partition.check_rank`); the visuals may use only the state's
    and the parameters' names (:func:`_check_visuals`).  ``variants``: which to check
    (default: the default and the completion variant; the others are checked at their first
    use).  The declaration itself is not changed."""
    variants = variants or tuple(dict.fromkeys((system.default_variant, system.completion_variant)))
    for v in variants:
        built(system).check_params(v)
    state = default_state(system)
    for v in variants:
        check_rank(system, v, state)  # a declared partition against the constraints' rank at the default state
    _check_visuals(system)


def _check_visuals(system: System) -> None:
    """Compile the visuals now, so that one using a name that is neither a state name nor a
    parameter is refused here, naming the shape (or frame), its field and the name
    (:func:`~nmkane_core.kernel.visuals.compile_visuals`), instead of when they are first drawn.
    Visuals compiled before come from the disk cache without sympy (and were checked when they
    were generated): a cached system still registers without importing it."""
    if system.visuals is not None:
        from ..kernel.visuals import compile_visuals

        compile_visuals(system)


def _add(system: System, check: bool) -> System:
    if not isinstance(system, System):
        raise InputError("register", type(system).__name__, "a System (or a function returning one)", "not a System")
    _load_builtin()  # built-in systems first (listing order; a user's may replace one)
    if check:
        check_system(system)
    with _LOCK:
        name = system.name
        if name in _USED:
            warnings.warn(
                f"nmkane: system {name!r} registered again; the new definition replaces the one "
                "already used in this process",
                stacklevel=3,
            )
        _FACTORIES[name] = lambda: system
        _BUILT[name] = system
        _USED.discard(name)
        _bump()
    return system


@overload
def register(system: System, *, check: bool = True) -> System: ...
@overload
def register(system: str, *, check: bool = True) -> Callable[[Callable[[], System]], Callable[[], System]]: ...
@overload
def register(system: Callable[[], System], *, check: bool = True) -> Callable[[], System]: ...


def register(system, *, check: bool = True):
    """Make a system available by its name, after checking it (:func:`check_system`).

    ``register(System(...))``; or as a decorator on a function returning the system
    (``@register``); ``@register("name")`` also checks that the system has that name.
    ``check=False`` skips the checks against the models (they then happen at first use).
    """
    if isinstance(system, System):
        return _add(system, check)
    if isinstance(system, str):
        expected = system

        def deco(factory):
            built = factory()
            if isinstance(built, System) and built.name != expected:
                raise InputError(
                    "register", expected, f"the system's own name ({built.name!r})", "two names for one system"
                )
            _add(built, check)
            return factory

        return deco
    if callable(system):
        _add(system(), check)
        return system
    raise InputError("register", system, "a System, a function returning one, or a name", "not a System")


def unregister(name: str) -> None:
    """Forget a registered system (no error if it is not registered)."""
    with _LOCK:
        _FACTORIES.pop(name, None)
        _BUILT.pop(name, None)
        _USED.discard(name)
        _bump()


def _bump() -> None:
    global _generation
    _generation += 1


def generation() -> int:
    """A number that changes whenever a system is registered or removed (cache key for catalogues)."""
    _load_builtin()
    return _generation


def _load_builtin() -> None:
    global _builtin_loaded, _builtin_ready
    if _builtin_ready:  # another thread may be loading: only a finished load skips the lock
        return
    with _LOCK:
        if _builtin_loaded:  # loaded, or being loaded by this very thread (plug-ins registering)
            return
        _builtin_loaded = True
        from ..systems import BUILTIN

        for name, factory in BUILTIN.items():
            _FACTORIES.setdefault(name, factory)
        from .plugins import load_default_plugins

        load_default_plugins()
        _builtin_ready = True


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
        _USED.add(name)
        return _BUILT[name]
