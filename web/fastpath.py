"""The per-frame hot path of the animation, made cheap: the classroom budget.

Measured (cProfile with a CPU-time clock in the animation thread, 8 sessions): a frame of
one session cost about 1.5 ms of CPU, and most of it was viser's bookkeeping, not ours —

* about half in following the camera: ``CameraHandle.position`` and ``.look_at`` each
  recompute the camera's orientation (``_update_wxyz``: SO(3) exponentials, ``allclose``)
  although only the two messages reach the browser;
* about a third in moving scene nodes: every ``handle.position = …`` / ``.wxyz = …``
  goes through ``_set_pose_vector``, whose ``np.allclose`` change test alone costs
  ~100 µs for three numbers.

:func:`install` replaces ``viser._scene_handles._set_pose_vector`` by an equivalent in
plain Python (same checks: arity, a no-op when unchanged within ``allclose``'s default
tolerances, the node's state updated in place, the same message queued); it applies to
every scene however it is declared.  :func:`follow_camera` sends the two camera messages
the setters would send and keeps viser's camera state consistent, without the orientation
(nothing of ours reads it; the browser reports its own camera back).

Both reach into viser 1.1 internals, through :mod:`web.viser_compat`: :func:`install`
leaves viser alone when the function it replaces has another signature, and
:func:`follow_camera` falls back to the setters when the camera differs (correct, only
slower).
"""

from __future__ import annotations

import math

import numpy as np

from . import viser_compat as compat

RTOL, ATOL = 1e-5, 1e-8  # np.allclose's defaults, as viser's change test

_installed = False


def _unchanged(new: tuple[float, ...], current) -> bool:
    """``np.allclose(new, current)`` for a few numbers, without numpy's overhead."""
    return all(abs(a - b) <= ATOL + RTOL * abs(b) for a, b in zip(new, current.tolist(), strict=True))


def _as_tuple(value, length: int) -> tuple[float, ...]:
    """viser's ``cast_vector``: a tuple of ``length`` floats (ValueError on another length)."""
    if isinstance(value, np.ndarray):
        if value.shape != (length,):
            raise ValueError(f"Expected vector of shape {(length,)}, but got {value.shape} instead")
        return tuple(value.tolist())
    if len(value) != length:
        raise ValueError(f"Expected vector of length {length}, but got {len(value)} instead")
    return tuple(map(float, value))


def _set_pose_vector(current, value, length, queue, make_message) -> None:
    """Drop-in for ``viser._scene_handles._set_pose_vector`` (see the module docstring)."""
    cast = _as_tuple(value, length)
    if _unchanged(cast, current):
        return
    current[:] = cast
    queue(make_message(cast))


def install() -> bool:
    """Put the fast pose setter in place (idempotent); False if viser's differs from the
    one this replaces (then nothing is changed)."""
    global _installed
    if _installed:
        return True
    _installed = compat.replace_pose_setter(_set_pose_vector)
    return _installed


def follow_camera(camera, position, look_at) -> None:
    """Move a client's camera to ``position`` looking at ``look_at`` (3-vectors): the
    messages ``camera.position = …; camera.look_at = …`` send, without recomputing the
    orientation.  Falls back to the setters if viser's camera differs from 1.1's."""
    current = compat.camera_pose(camera)
    if current is None:
        camera.position = position
        camera.look_at = look_at
        return
    px, py, pz = _as_tuple(np.asarray(position, dtype=float), 3)
    ax, ay, az = _as_tuple(np.asarray(look_at, dtype=float), 3)
    pos, at = (px, py, pz), (ax, ay, az)
    if not all(map(math.isfinite, pos + at)):
        raise ValueError(f"camera position {pos} / look_at {at}: finite numbers are needed")
    compat.send_camera(
        camera,
        None if _unchanged(pos, current[0]) else pos,
        None if _unchanged(at, current[1]) else at,
    )
