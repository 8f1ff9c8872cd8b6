"""``nmkane bench``'s rows for the IFToMM multibody benchmarks A01–A05.

Each row runs one problem's case through :func:`~nmkane_core.run.simulate.simulate` with the
catalogue's name, warm (the kernels compiled once before), and reports the process's CPU
time for the whole call (best of three) beside the CPU time the OpenSim 3.2 implementation
published for the same case (``OPENSIM_CPU_S`` of each system module; RehabEngGroup/
MBSbenchmarksInOpenSim, an Intel i5-4570 at 3.2 GHz), and the error achieved against what
each module gives as the truth: the exact motion (A01, A02), the energy balance that is zero
in theory (A03, A04) with the CWI/Bari test set's reference angles (A03), the conserved axial
momentum and a dissipation that never gains energy (A05, no published CPU time).

The cases are OpenSim's: A01 10 s (the benchmark's own 2000 s too, without ``quick``), A02
with N = 2 for 10 s, A03 0.05 s, A04 10 s, A05 10 s; the step and the integrator are the
catalogue's defaults (fixed-step Kutta–Merson).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from ..kernel.built import built
from ..run.plan import resolve
from ..run.registry import get_system
from ..run.simulate import simulate
from ..systems import iftomm_a01, iftomm_a02, iftomm_a03, iftomm_a04

__all__ = ["iftomm_rows"]


def _cpu(settings: dict, repeat: int):
    """Best-of-``repeat`` process CPU time of one warm ``simulate`` call (and its run)."""
    plan = resolve(settings)
    run = simulate(plan, progress=False)  # warm: compiles on a first use, loads the kernels otherwise
    best = float("inf")
    for _ in range(repeat):
        t0 = time.process_time()
        run = simulate(plan, progress=False)
        best = min(best, time.process_time() - t0)
    if run.summary["status"] != "ok":
        raise RuntimeError(f"{settings['system']}: {run.summary['status']}: {run.summary['message']}")
    return best, run


def _a01(run) -> tuple[str, dict]:
    err = iftomm_a01.acceptance(run.t, run.state["x"], run.state["y"])["P1_position"]
    return f"P1 within {err:.1e} m of the exact motion (allowed 1e-3)", {"P1_position": err}


def _a02(run) -> tuple[str, dict]:
    qn, un = iftomm_a02.names(2)
    x = np.column_stack([run.state[k] for k in (*qn, *un)])
    acc = iftomm_a02.acceptance(run.t, x, 2, energy=run.energy)
    text = (
        f"B0 within {acc['B0_position']:.1e} m, {acc['B0_velocity']:.1e} m/s of the exact motion "
        f"(allowed 1e-3), max |ΔE| {acc['energy_drift']:.1e} J"
    )
    return text, acc


def _a03(run) -> tuple[str, dict]:
    k = int(np.argmin(np.abs(run.t - 0.03)))
    angles = [run.state[n][k] for n in iftomm_a03.NAMES]
    acc = iftomm_a03.acceptance(run.t, run.energy, angles)
    text = (
        f"max |ΔU| {acc['energy_balance']:.1e} J (0 in theory); the 7 angles at 0.03 s within "
        f"{acc['angles_at_0.03']:.1e} rad of the test set's solution"
    )
    return text, acc


def _a04(run) -> tuple[str, dict]:
    drift = run.summary["max_abs_energy_drift"]
    swing = np.ptp(run.state["q1"])
    return f"max |ΔE| {drift:.1e} J (0 in theory); q1 swings over {swing:.4f} rad", {"energy_drift": drift}


def _a05(run) -> tuple[str, dict]:
    """The axial momentum's drift (relative; from the reference kernel's outputs, every 100th
    row) and the largest energy gain between rows (the dampers only dissipate)."""
    from ..symbolic.reference import ReferenceKernel

    system = get_system("iftomm-a05")
    model = built(system).model()
    ref = ReferenceKernel(built(system).derivation())
    p = np.array([system.parameter(str(s)).default for s in model.params])
    x = np.column_stack([run.state[str(s).removesuffix("(t)")] for s in (*model.q, *model.u)])[::100]
    hz = np.array([ref.outputs(0.0, xi, p)[0] for xi in x])
    acc = {
        "Hz_drift": float(np.abs(hz - hz[0]).max() / abs(hz[0])),
        "energy_increase": float(np.diff(run.energy).max(initial=0.0)),
    }
    text = f"axial momentum drift {acc['Hz_drift']:.1e} (relative); largest energy gain {acc['energy_increase']:.1e} J"
    return text, acc


Workload = tuple[str, dict, "float | None", Callable[..., tuple[str, dict]]]


def _workloads(quick: bool) -> list[Workload]:
    """(label, settings, OpenSim 3.2 CPU time or None, the error of a run) of each row."""
    rows: list[Workload] = [
        ("A01 simple pendulum, 10 s", {"system": "iftomm-a01", "t_final": 10.0}, iftomm_a01.OPENSIM_CPU_S, _a01),
        ("A02 N-four-bar, N = 2, 10 s", {"system": "iftomm-a02"}, iftomm_a02.OPENSIM_CPU_S, _a02),
        ("A03 Andrews' squeezer, 0.05 s", {"system": "iftomm-a03", "t_final": 0.05}, iftomm_a03.OPENSIM_CPU_S, _a03),
        ("A04 Bricard's mechanism, 10 s", {"system": "iftomm-a04"}, iftomm_a04.OPENSIM_CPU_S, _a04),
        ("A05 stiff flyball governor, 10 s", {"system": "iftomm-a05"}, None, _a05),
    ]
    if not quick:  # the benchmark's own duration, measured with its 4000 output steps
        rows.insert(1, ("A01 simple pendulum, 2000 s", {"system": "iftomm-a01", "every": 500}, None, _a01))
    return rows


def iftomm_rows(add, quick: bool) -> None:
    """One row per problem: CPU time of the whole warm ``simulate`` call (best of 3; 1 with
    ``quick``) against OpenSim 3.2's published time for the case, the error in the note.
    The target is OpenSim's time (another machine: an i5-4570 at 3.2 GHz)."""
    repeat = 1 if quick else 3
    for label, settings, opensim, error in _workloads(quick):
        settings = {**settings, "integrator": "kutta-merson"}
        cpu, run = _cpu(settings, repeat)
        text, acc = error(run)
        dt = run.settings["dt"]
        versus = f"OpenSim 3.2: {opensim} s" if opensim is not None else "OpenSim 3.2: no published time"
        row = add(
            f"IFToMM {label}, dt={dt:g}, Kutta–Merson, CPU time",
            cpu,
            run.summary["rhs_evals"] / run.summary["wall_time_s"],
            f"≤ {opensim} s (OpenSim)" if opensim is not None else None,
            cpu <= opensim if opensim is not None else None,
            f"({versus}; loop {run.summary['wall_time_s'] * 1e3:.0f} ms; solve {run.settings['solve']}, "
            f"projection {run.settings['projection']}; {text})",
        )
        row.update({"cpu_s": cpu, "opensim_cpu_s": opensim, "error": acc})


def main(quick: bool = False) -> None:
    """Measure and print only these rows (``nmkane bench`` measures them with the others)."""
    rows: list[dict] = []

    def add(workload, wall, evals=None, target=None, ok=None, note=""):
        rows.append({"workload": workload, "wall_s": wall, "target": target, "pass": ok, "note": note})
        return rows[-1]

    iftomm_rows(add, quick)
    for r in rows:
        verdict = {True: "PASS", False: "FAIL", None: ""}[r["pass"]]
        print(f"{r['workload']}: {r['wall_s'] * 1e3:.1f} ms {r['target'] or ''} {verdict}\n    {r['note']}")
