"""Long runs of the closed-loop cases with the numpy reference (plain-Python Kutta–Merson):
the numbers quoted in docs/closed-loops.md for the rank-robust solve.

    PYTHONPATH=. python scripts/closed_loops_validate.py [--t-final 10] [--dt 1e-3 5e-4]
                                                         [--case a02 parallelogram bricard]

A02 N = 2 (the N-four-bar crossing the horizontal position) and the three-crank
parallelogram declared with all four closure equations, against their exact motion; Bricard's
mechanism (A04, five closure equations of rank four) against the same mechanism declared
without the redundant equation (the paper's path), and its energy drift.  Every run:
Kutta–Merson at fixed Δt, Γ1 = −20, Γ2 = −100, ``solve="auto"`` (the paper's path where J2
is well-conditioned, the robust solve elsewhere) and the mass-metric post-step projection.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.integrate import solve_ivp

from nmkane_core.integrate.methods import KUTTA_MERSON
from nmkane_core.symbolic.derivation import derive
from nmkane_core.symbolic.reference import ReferenceKernel, integrate_reference, integrate_reference_adaptive
from nmkane_core.systems import iftomm_a02, iftomm_a04


def pendulum(t, th0, w0, inertia, K):
    sol = solve_ivp(
        lambda _t, y: [y[1], -K / inertia * math.cos(y[0])], (0, t[-1]), [th0, w0], "DOP853", t, rtol=1e-13, atol=1e-13
    )
    return sol.y


def run(ref, x0, p, dt, T, m, solve="auto", project=True):
    ref.reset()
    t0 = time.perf_counter()
    t, xs = integrate_reference(
        ref,
        x0,
        p,
        dt,
        round(T / dt),
        KUTTA_MERSON,
        None,
        -20 * np.eye(m),
        -100 * np.eye(m),
        project=project,
        solve=solve,
    )
    wall = time.perf_counter() - t0
    E = np.array([ref.energy(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
    viol = max(np.abs(ref.violation(ti, xi, p)).max() for ti, xi in zip(t, xs, strict=True))
    return t, xs, float(np.abs(E - E[0]).max()), viol, wall, len(ref.switches)


def adaptive_run(ref, x0, p, T, m, project=True, tangent=True):
    """Adaptive Kutta–Merson (rtol 1e-10, atol 1e-12: the run defaults) with the projection."""
    ref.reset()
    t0 = time.perf_counter()
    ts, xs, rejected = integrate_reference_adaptive(
        ref,
        x0,
        p,
        T,
        KUTTA_MERSON,
        None,
        -20 * np.eye(m),
        -100 * np.eye(m),
        project=project,
        tangent=tangent,
        solve="auto",
    )
    wall = time.perf_counter() - t0
    En = np.array([ref.energy(ti, xi, p) for ti, xi in zip(ts, xs, strict=True)])
    return ts, xs, float(np.abs(En - En[0]).max()), wall, rejected, len(ref.switches)


def exact_errors(t, xs, inertia, K, L=1.0):
    n = xs.shape[1] // 2
    th, w = pendulum(t, xs[0, 0], xs[0, n], inertia, K)
    pos = max(np.abs(np.cos(xs[:, 0]) - np.cos(th)).max(), np.abs(np.sin(xs[:, 0]) - np.sin(th)).max()) * L
    vel = (
        max(
            np.abs(-np.sin(xs[:, 0]) * xs[:, n] + np.sin(th) * w).max(),
            np.abs(np.cos(xs[:, 0]) * xs[:, n] - np.cos(th) * w).max(),
        )
        * L
    )
    crossings = int(np.sum(np.diff(np.sign(np.sin(xs[:, 0]))) != 0))
    return pos, vel, crossings


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-final", type=float, default=10.0)
    ap.add_argument("--dt", type=float, nargs="+", default=[1e-3])
    ap.add_argument("--case", nargs="+", default=["a02", "parallelogram", "bricard"])
    ap.add_argument("--no-projection", action="store_true")
    ap.add_argument("--adaptive", action="store_true", help="A02 with adaptive Kutta–Merson (rtol 1e-10, atol 1e-12)")
    ap.add_argument("--raw-error", action="store_true", help="adaptive: control the error estimate as it is")
    args = ap.parse_args()
    T, project = args.t_final, not args.no_projection
    print(f"Kutta–Merson, {T} s, Γ1 = −20, Γ2 = −100, solve=auto, projection={project}")
    if "a02" in args.case:
        md = iftomm_a02.model(2)
        ref = ReferenceKernel(derive(md))
        st = iftomm_a02.initial_state(2)
        x0 = np.array([st[str(v)] for v in md.q + md.u])
        inertia, K = iftomm_a02.pendulum_constants(2)
        for dt in args.dt:
            t, xs, dE, viol, wall, sw = run(ref, x0, np.array([1.0, 1.0, 9.81]), dt, T, 4, project=project)
            pos, vel, cr = exact_errors(t, xs, inertia, K)
            print(
                f"A02 N=2 dt={dt:g}: B0 position {pos:.2e} m, velocity {vel:.2e} m/s, |ΔE| {dE:.2e} J, "
                f"|ψ| {viol:.2e}, {cr} horizontal crossings, {sw} solve changes, {wall:.0f} s"
            )
    if args.adaptive:
        md = iftomm_a02.model(2)
        ref = ReferenceKernel(derive(md))
        st = iftomm_a02.initial_state(2)
        x0 = np.array([st[str(v)] for v in md.q + md.u])
        inertia, K = iftomm_a02.pendulum_constants(2)
        t, xs, dE, wall, rej, sw = adaptive_run(
            ref, x0, np.array([1.0, 1.0, 9.81]), T, 4, project=project, tangent=not args.raw_error
        )
        pos, vel, cr = exact_errors(t, xs, inertia, K)
        print(
            f"A02 N=2 adaptive Kutta–Merson ({'raw' if args.raw_error else 'tangent'} error): {len(t) - 1} steps "
            f"({rej} rejected), B0 position {pos:.2e} m, "
            f"velocity {vel:.2e} m/s, |ΔE| {dE:.2e} J, {cr} crossings, {sw} solve changes, {wall:.0f} s"
        )
        return
    if "parallelogram" in args.case:
        md = iftomm_a04.parallelogram_model(redundant=True)
        ref = ReferenceKernel(derive(md))
        st = iftomm_a04.parallelogram_state()
        x0 = np.array([st[str(v)] for v in md.q + md.u])
        inertia, K = iftomm_a04.parallelogram_constants()
        for dt in args.dt:
            t, xs, dE, viol, wall, sw = run(ref, x0, np.array([1.0, 1.0, 9.81]), dt, T, 4, project=project)
            pos, vel, cr = exact_errors(t, xs, inertia, K)
            print(
                f"parallelogram, 4 closure equations (rank 3) dt={dt:g}: tip position {pos:.2e} m, velocity "
                f"{vel:.2e} m/s, |ΔE| {dE:.2e} J, |ψ| {viol:.2e}, {cr} crossings, {sw} solve changes, {wall:.0f} s"
            )
    if "bricard" in args.case:
        p = np.array([1.0, 1.0, 0.1, 9.81])
        x0 = np.zeros(10)
        red = ReferenceKernel(derive(iftomm_a04.bricard_model()))
        classic = ReferenceKernel(derive(iftomm_a04.bricard_model(redundant=False)))
        for dt in args.dt:
            t, xs, dE, viol, wall, sw = run(red, x0, p, dt, T, 5, project=project)
            _, xc, dEc, _, wallc, _ = run(classic, x0, p, dt, T, 4, solve="paper", project=project)
            P3 = np.array([red.outputs(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
            P3c = np.array([classic.outputs(ti, xi, p) for ti, xi in zip(t, xc, strict=True)])
            print(
                f"Bricard (5 equations, rank 4) dt={dt:g}: |ΔE| {dE:.2e} J, |ψ| {viol:.2e}, {sw} solve changes, "
                f"{wall:.0f} s; "
                f"P3 vs the 4-equation paper path {np.abs(P3 - P3c).max():.2e} m (its |ΔE| {dEc:.2e}, {wallc:.0f} s); "
                f"P3 range x {P3[:, 0].min():.3f}..{P3[:, 0].max():.3f}, y {P3[:, 1].min():.3f}..{P3[:, 1].max():.3f}, "
                f"z {P3[:, 2].min():.3f}..{P3[:, 2].max():.3f}"
            )


if __name__ == "__main__":
    main()
