"""The 3D web app: the Appell–Hamel mechanism (and the sliding particle) live in a browser.

This module is the app's public face; the parts live in:

* :mod:`web.server` — the viser server, one session per browser, the animation thread,
  :func:`launch_app` / :func:`launch` (background) and :func:`main` (``python -m web``);
* :mod:`web.session` — one browser's page (:class:`MechanismApp`): controls, scene, camera
  and trajectory wired together;
* :mod:`web.controls` — control handles built from data, and the guard that refuses
  non-finite or out-of-range slider values;
* :mod:`web.runs` — re-simulation on a control change via :mod:`web.worker`;
* :mod:`web.panel` — plots, summary, status text and the derived-matrices panel;
* :mod:`web.camera` — following the mechanism while keeping the viewer's orbit;
* :mod:`web.systems` — what is specific to each system (controls, runs, plots, scene of
  :mod:`web.scene`) behind one small interface, :class:`~web.systems.SystemView`.

Geometry lives in :mod:`web.geometry`, plot data in :mod:`web.plots`, the matrices in
:mod:`web.matrices`.
"""

from __future__ import annotations

from .controls import INTEGRATORS, dt_of
from .runs import TIME_LIMIT_S, Trajectory
from .server import FPS, REFRESH_HZ, WebApp, launch, launch_app, main, warm
from .session import MechanismApp
from .systems import AppellHamelView, ParticleView

AH, PT = AppellHamelView.title, ParticleView.title
AH_DEFAULTS = {c.attr: c.default for c in AppellHamelView.controls}
PT_DEFAULTS = {c.attr: c.default for c in ParticleView.controls}

__all__ = [
    "AH",
    "AH_DEFAULTS",
    "FPS",
    "INTEGRATORS",
    "PT",
    "PT_DEFAULTS",
    "REFRESH_HZ",
    "TIME_LIMIT_S",
    "MechanismApp",
    "Trajectory",
    "WebApp",
    "dt_of",
    "launch",
    "launch_app",
    "main",
    "warm",
]
