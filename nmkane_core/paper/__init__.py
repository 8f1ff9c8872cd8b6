"""The paper's Figures 2–9 and 11–18, regenerated, and a report of its claims.

``nmkane figures [--out DIR]`` (or :func:`make_figures`) runs every simulation the
figures of Bajodah, Hodges & Chen (2005) need, draws each figure as a PNG with the
paper's caption, axis labels and units, checks the paper's claims against the numbers
measured now, and writes ``report.md``, ``report.html`` and ``report.json``: each figure
beside a table (claim, paper value, measured now, PASS/FAIL), a short "what this shows"
paragraph, and the settings of every run as a CLI command and a REST body.

Choices the paper leaves open (stated again in the report):

* Example 1 (Appell–Hamel): the paper states neither the horizon nor the step of
  Figs. 2–9.  We use 20 s (by then θ has settled and the load has fallen ≈ 50 m) and the
  Kutta–Merson scheme with Δt = 0.01 s, the project's defaults.
* Example 2: every run uses fixed-step Kutta–Merson, as the paper does; 500 s for
  Figs. 11–15 and 17 (the paper's), 1 h for Fig. 16 (the paper's), and 500 s for Fig. 18
  (not stated).  The fine-step reference of Fig. 16 is the minimal equation (137) at
  Δt = 0.001 s.

``quick=True`` shortens what a claim allows: Fig. 18 over 100 s and Fig. 16's reference at
Δt = 0.005 s.  Figs. 11–15 and 17 always run the paper's full 500 s: Fig. 15's bound needs
it, and at Δt = 0.001 s the undamped drift only starts to grow after ≈ 120 s.

The modules, in the order the work is done:

* :mod:`.runs` — the run plan (:func:`run_plan`) and making it (:func:`collect_runs`);
* :mod:`.claims` — the paper's claims, one function each (:func:`evaluate_claims`);
* :mod:`.figure_specs` and :mod:`.drawing` — the figures (matplotlib only inside drawing functions);
* :mod:`.rerun` — every run as a CLI command and a REST request;
* :mod:`.report` — the Markdown, HTML and JSON report;
* :mod:`.make` — :func:`make_figures`, all of the above; :mod:`.cli` — ``python -m nmkane_core.paper``.

The test suite (tests/test_paper_claims.py, tests/test_figures.py) asserts the claims and the report.
"""

from __future__ import annotations

import importlib
from typing import Any

_HOMES = {
    "FAIL": "claims",
    "INFO": "claims",
    "NOT_RUN": "claims",
    "PASS": "claims",
    "Claim": "claims",
    "evaluate_claims": "claims",
    "FigureResult": "figure_specs",
    "make_figures": "make",
    "Report": "report",
    "cli_command": "rerun",
    "rest_body": "rerun",
    "Runs": "runs",
    "collect_runs": "runs",
    "run_plan": "runs",
}
__all__ = sorted(_HOMES)


def __getattr__(name: str) -> Any:  # PEP 562: `nmkane figures --help` loads none of the run machinery
    if name in _HOMES:
        return getattr(importlib.import_module(f".{_HOMES[name]}", __name__), name)
    raise AttributeError(name)
