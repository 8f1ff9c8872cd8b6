"""How IFToMM A02's cost grows with its size N (N windows: 2N + 1 rods, 2N + 1 coordinates,
2N closure equations): register (derive and check, which compiles the model's C functions), the
first 20 s run, and a second 20 s run's cost per right-hand-side evaluation (the generic core: a
20 s run is below the specialised build's threshold).  One JSON line per call; docs/performance.md has the table.

    NMKANE_CACHE_DIR=/tmp/a02-n10 python scripts/a02_scaling.py 10 cold     # an empty cache
    NMKANE_CACHE_DIR=/tmp/a02-n10 python scripts/a02_scaling.py 10 cached   # a fresh process, cached

Run each under ``/usr/bin/time`` for the process's wall and CPU time, children included.
"""

from __future__ import annotations

import json
import sys
import time


def main(argv: list[str]) -> None:
    t0 = time.perf_counter()
    n_windows, phase = int(argv[0]), argv[1] if len(argv) > 1 else ""
    from nmkane_core import simulate
    from nmkane_core.run.registry import register
    from nmkane_core.systems.iftomm_a02 import iftomm_a02

    out: dict = {"N": n_windows, "phase": phase}
    t = time.perf_counter()
    system = register(iftomm_a02(n_windows))
    out["register_s"] = round(time.perf_counter() - t, 2)
    settings = {"system": system.name, "t_final": 20.0, "dt": 1e-3, "every": 50}  # the table: at Δt = 1e-3
    t = time.perf_counter()
    run = simulate(settings, progress=False)
    out["first_run_s"] = round(time.perf_counter() - t, 2)
    out["status"] = run.status
    out["process_to_first_result_s"] = round(time.perf_counter() - t0, 2)
    run = simulate(settings, progress=False)
    out["run_20s_wall_s"] = round(run.summary["wall_time_s"], 3)
    out["us_per_eval"] = round(1e6 * run.summary["wall_time_s"] / run.summary["rhs_evals"], 2)
    out["max_abs_energy_drift_J"] = run.summary["max_abs_energy_drift"]
    print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
