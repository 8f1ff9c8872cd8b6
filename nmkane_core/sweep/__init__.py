"""Sweeps over run settings, parameters and initial values, on local cores or a Dask cluster,
and the choice of Baumgarte gains (``nmkane sweep``, ``nmkane tune``).

* `.spec` — ``--grid``/``--log-grid``/``--sample`` parsing, the points of a sweep;
* `.executors` — this process, local worker processes, Dask (batches, kernels loaded once
  per worker);
* `.output` — the streamed, resumable CSV/Parquet output;
* `.runner` — `run_sweep`;
* `.plot` — heatmap or lines of a metric (matplotlib, the ``figures`` extra);
* `.tune` — Γ, Γ1, Γ2 chosen within the integrator's stability region.
"""

from __future__ import annotations

from .output import read_rows
from .runner import SweepResult, run_sweep
from .spec import Axis, SweepSpec, apply_point, parse_axis, parse_sample, point_key, sweep_spec

__all__ = [
    "Axis",
    "SweepResult",
    "SweepSpec",
    "apply_point",
    "parse_axis",
    "parse_sample",
    "point_key",
    "read_rows",
    "run_sweep",
    "sweep_spec",
]
