"""The 3D web app: every registered system — the paper's two examples, the catalogue, systems
plugged in with ``--systems`` — live in a browser, through one generic page.

This module is the app's public face; the parts live in:

* :mod:`web.server` — the viser server, one session per browser, the animation thread,
  :func:`launch_app` / :func:`launch` (background) and :func:`main` (``python -m web``);
* :mod:`web.session` — one browser's page (:class:`MechanismApp`): a small coordinator of
  :mod:`web.playback` (the shown time, the frames), :mod:`web.scenes` (scene switching) and
  :mod:`web.session_runs` (a control change run and installed);
* :mod:`web.generic` — the one system view, :class:`~web.generic.GenericView`: controls,
  runs (with compare ghosts), plots and scene from the core system's declaration;
* :mod:`web.declared` — the visuals a system declares (:mod:`nmkane_core.declare.visuals`) as a
  viser scene; :mod:`web.framing` — what the camera frames of it (the mechanism's parts);
* :mod:`web.controls` — control handles built from data, and the guard that refuses
  non-finite or out-of-range slider values;
* :mod:`web.runs` — re-simulation on a control change via :mod:`web.worker`;
* :mod:`web.panel` — plots, summary, status text and the derived-matrices panel;
* :mod:`web.camera` — following the system while keeping the viewer's orbit;
* :mod:`web.labels` — which corner of its text each 3D label holds, so that none covers another
  in the browser's picture;
* :mod:`web.viser_compat` — every use of viser's private API, in one place.

Geometry helpers live in :mod:`web.geometry`, plot data in :mod:`web.plots`, the matrices
in :mod:`web.matrices`.  Nothing in ``web/`` names a system (a test checks it).
"""

from __future__ import annotations

from .controls import INTEGRATORS, dt_of
from .generic import GenericView, scene_choices
from .runs import TIME_LIMIT_S, Trajectory
from .server import FPS, REFRESH_HZ, WebApp, launch, launch_app, main, warm
from .session import MechanismApp

__all__ = [
    "FPS",
    "INTEGRATORS",
    "REFRESH_HZ",
    "TIME_LIMIT_S",
    "GenericView",
    "MechanismApp",
    "Trajectory",
    "WebApp",
    "dt_of",
    "launch",
    "launch_app",
    "main",
    "scene_choices",
    "warm",
]
