"""``nmkane bench``'s rows for the constraint forces: a run with them on against off.

``RunSettings.constraint_forces`` switches off F_c and λ in the compiled loops and the declared
forces at points computed after them (:mod:`nmkane_core.run.forces`).
"""

from __future__ import annotations

import os
import time

from ..run.plan import resolve
from ..run.simulate import simulate

__all__ = ["FORCES_TARGET", "forces_rows"]


#: the forces' cost target: per step, the compiled loop with forces on vs off
FORCES_TARGET = 1.15


def _forces_cost(settings: dict, repeat: int = 5) -> tuple[dict, dict]:
    """Best-of-``repeat`` timings of one run with its constraint forces on and off, the two
    interleaved (a busy machine slows both alike): ``{"loop": integration wall time,
    "total": the whole simulate call}`` for each."""
    plans = {on: resolve({**settings, "constraint_forces": on}) for on in (True, False)}
    best = {on: {"loop": float("inf"), "total": float("inf")} for on in plans}
    for plan in plans.values():
        simulate(plan, progress=False)  # warm (the point forces compile on a first use)
    for _ in range(repeat):
        for on, plan in plans.items():
            t0 = time.perf_counter()
            run = simulate(plan, progress=False)
            best[on]["total"] = min(best[on]["total"], time.perf_counter() - t0)
            best[on]["loop"] = min(best[on]["loop"], run.summary["wall_time_s"])
    return best[True], best[False]


def forces_rows(add, quick: bool) -> None:
    """Constraint forces on against off (``RunSettings.constraint_forces``): F_c and λ in the
    compiled loops, the declared forces at points after them.  Each workload twice: every
    step recorded (``every=1``: a force for every step, the loop's worst case) and as the rows
    above run it (``every=1000``).  The target is the loop's cost per step."""
    ah_t = 50.0 if quick else 500.0
    workloads = [
        (
            f"Appell–Hamel NC, Kutta–Merson, dt=0.001, {ah_t:g} s",
            {"system": "appell-hamel", "model": "nonlinear", "integrator": "kutta-merson", "dt": 0.001},
            ah_t,
        ),
        (
            "Whipple bicycle, Kutta–Merson, dt=0.001, 10 s",
            {"system": "whipple-bicycle", "integrator": "kutta-merson", "dt": 0.001, "initial": {"u4": 0.5}},
            10.0,
        ),
    ]
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    for label, base, horizon in workloads:
        # every step recorded: 50 s of the long run (50,000 rows) stands for its per-step cost
        for every, t_final in ((1, min(horizon, 50.0)), (1000, horizon)):
            on, off = _forces_cost({**base, "t_final": t_final, "every": every})
            ratio = on["loop"] / off["loop"]
            add(
                f"constraint forces on/off: {label.replace(f'{horizon:g} s', f'{t_final:g} s')}, every={every}",
                on["total"],
                None,
                "loop ≤ +15 %/step" if every == 1 else None,
                ratio <= FORCES_TARGET if every == 1 else None,
                f"(loop {on['loop'] * 1e3:.1f} ms on, {off['loop'] * 1e3:.1f} ms off: {100 * (ratio - 1):+.1f} % "
                f"per step; whole run {on['total'] * 1e3:.1f} / {off['total'] * 1e3:.1f} ms; load {load:.1f})",
            )
