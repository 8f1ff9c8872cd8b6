"""IFToMM A02 (N = 2) started at 45°, 10 s, the catalogue's defaults: how far B0 is from the exact
motion at every step size, and how that moves with a round-off asymmetry in the start — the
numbers of docs/closed-loops.md §7.4.

    PYTHONPATH=. python scripts/a02_roundoff.py                 # the step-size table
    PYTHONPATH=. python scripts/a02_roundoff.py --perturb 20    # + 20 starts off by 1e-16 … 1e-13
    NMKANE_CORE_CFLAGS=-march=native NMKANE_CACHE_DIR=$(mktemp -d) PYTHONPATH=. python scripts/a02_roundoff.py

The third line compiles the core for this machine's CPU (its FMA instructions available): the table
must not change.
A perturbed start is a full state (every coordinate and speed given), one coordinate moved by
±10^U(−16, −13) (seeded): ``simulate`` checks it and the first projection takes it back onto the
constraints, but a round-off asymmetry between the cranks stays.
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from nmkane_core import simulate
from nmkane_core.systems import iftomm_a02

STEPS = ({"dt": 1e-3}, {"dt": 5e-4}, {"dt": 2e-4}, {"dt": 1e-4}, {"integrator": "kutta-merson-adaptive"})
NAMES = tuple(n for group in iftomm_a02.names(2) for n in group)


def errors(initial: dict, step: dict) -> dict[str, float]:
    r = simulate({"system": "iftomm-a02", "t_final": 10.0, "every": 10, "initial": initial, **step}, progress=False)
    x = np.column_stack([r.state[k] for k in NAMES])
    return {"status": r.summary["status"], **iftomm_a02.acceptance(r.t, x, 2, energy=r.energy)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--perturb", type=int, default=0, help="perturbed starts to run (each at the four fixed steps)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    th0 = math.pi / 4
    start = {"th0": th0, "dth0": -1.0 / math.sin(th0)}  # ẋ_B0 = 1 m/s
    print(f"{'step':<34}status  B0 position  B0 velocity  max |ΔE|")
    for step in STEPS:
        e = errors(start, step)
        label = ", ".join(f"{k}={v}" for k, v in step.items())
        pos, vel, de = e["B0_position"], e["B0_velocity"], e["energy_drift"]
        print(f"{label:<34}{e['status']:<8}{pos:.2e} m   {vel:.2e} m/s {de:.2e} J")
    if not args.perturb:
        return
    r = simulate({"system": "iftomm-a02", "t_final": 1e-3, "dt": 1e-3, "initial": start}, progress=False)
    full = {k: float(r.state[k][0]) for k in NAMES}
    rng = np.random.default_rng(args.seed)
    worst = np.zeros((args.perturb, 4))
    for i in range(args.perturb):
        name = NAMES[rng.integers(1, len(NAMES))]
        moved = {**full, name: full[name] + rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-16, -13)}
        worst[i] = [errors(moved, step)["B0_velocity"] for step in STEPS[:4]]
        print(f"{name:>5} {moved[name] - full[name]:+.1e}: " + "  ".join(f"{v:.1e}" for v in worst[i]))
    print(
        f"B0 velocity over {worst.size} runs: largest {worst.max():.2e} m/s, median {np.median(worst):.2e}, "
        f"above 2e-7: {int((worst > 2e-7).sum())}"
    )


if __name__ == "__main__":
    main()
