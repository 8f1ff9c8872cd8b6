"""Candidate constraint solves for closed loops, compared on the IFToMM A02 N-four-bar
crossing its singular (horizontal) positions and on the redundant three-crank parallelogram.

    PYTHONPATH=. python scripts/closed_loops_compare.py [--t-final 2] [--dt 1e-3] [--cost]

Every candidate gets the same numpy terms (Q, P, J = ∂[φ; ψ̇]/∂u, c = −(B1u + B2) + s with
the Baumgarte vector s, Γ1 = −20, Γ2 = −100) from :class:`ReferenceKernel` and returns u̇;
the integrator is the fixed-step Kutta–Merson of the paper, with or without the post-step
mass-metric projection (:meth:`ReferenceKernel.project`).  Reported: how the run ended,
the largest errors of B0's position and velocity against the exact parallelogram motion,
the largest energy drift and constraint violation.  ``--cost``: the linear algebra of one
evaluation at the benchmark's own size (N = 40: n = 81, m = 80), LAPACK through numpy.
The numbers are quoted in docs/closed-loops.md.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import scipy.linalg as sla

from nmkane_core.errors import SingularMatrix
from nmkane_core.integrate.methods import KUTTA_MERSON
from nmkane_core.symbolic.derivation import derive
from nmkane_core.symbolic.reference import ReferenceKernel, robust_solve
from nmkane_core.systems import iftomm_a02, iftomm_a04


# ------------------------------------------------------------------ candidate solves
def gauss_qr(Q, P, J, c, max_rank=None):
    """Gauss's principle: Cholesky of Q, QR with column pivoting of L⁻¹Jᵀ (the choice)."""
    return robust_solve(Q, P, J, c, max_rank=max_rank).udot


def gauss_normal(Q, P, J, c, max_rank=None, tol=1e-12):
    """Udwadia–Kalaba with the normal matrix: a + Q⁻¹Jᵀ (J Q⁻¹ Jᵀ)⁺ (c − J a), pinv by eigh."""
    cf = sla.cho_factor(Q)
    a = sla.cho_solve(cf, P)
    QiJt = sla.cho_solve(cf, J.T)
    G = J @ QiJt
    w, V = np.linalg.eigh(G)
    keep = w > tol * w.max()
    if max_rank is not None:
        keep[: len(w) - max_rank] = False  # eigh sorts ascending: keep the largest max_rank
    Gp = (V[:, keep] / w[keep]) @ V[:, keep].T
    return a + QiJt @ (Gp @ (c - J @ a))


def augmented_lagrangian(Q, P, J, c, max_rank=None, alpha_rel=1e8, iterations=30, tol=1e-12):
    """Bayo & Ledesma's acceleration-level augmented Lagrangian: (Q + αJᵀJ) u̇ = P + Jᵀλ + αJᵀc,
    λ ← λ + α(c − J u̇), until J u̇ = c (α relative to |Q| / |J|²)."""
    alpha = alpha_rel * np.abs(Q).max() / max(np.abs(J).max() ** 2, 1e-300)
    cf = sla.cho_factor(Q + alpha * J.T @ J)
    lam = np.zeros(J.shape[0])
    for _ in range(iterations):
        udot = sla.cho_solve(cf, P + J.T @ lam + alpha * J.T @ c)
        r = c - J @ udot
        lam += alpha * r
        if np.abs(r).max() <= tol * max(1.0, np.abs(c).max()):
            break
    return udot


CANDIDATES = {"gauss-qr": gauss_qr, "gauss-normal": gauss_normal, "augmented-lagrangian": augmented_lagrangian}


# ------------------------------------------------------------------ runs
def run(ref, x0, p, dt, nsteps, G1, G2, how, project):
    A, b, cc = KUTTA_MERSON.A, KUTTA_MERSON.b, KUTTA_MERSON.c

    def f(t, x):
        if how == "paper":
            return ref.rhs(t, x, p, None, G1, G2)
        Q, P, J, bb, s = ref._terms(t, x, p, None, G1, G2)
        return ref._xdot(t, x, p, CANDIDATES[how](Q, P, J, -bb + s, max_rank=ref.max_rank))

    x = np.array(x0, float)
    ts, xs = [0.0], [x.copy()]
    status = "ok"
    for k in range(nsteps):
        t = k * dt
        K = []
        try:
            for i in range(len(cc)):
                xi = x + dt * sum((A[i, j] * K[j] for j in range(i)), np.zeros_like(x))
                K.append(f(t + cc[i] * dt, xi))
        except SingularMatrix as e:
            status = f"singular at t = {e.t:.4g} s"
            break
        x = x + dt * sum(bi * ki for bi, ki in zip(b, K, strict=True))
        if not np.all(np.isfinite(x)):
            status = f"diverged at t = {t:.4g} s"
            break
        if project:
            x = ref.project((k + 1) * dt, x, p)
        ts.append((k + 1) * dt)
        xs.append(x.copy())
    return status, np.array(ts), np.array(xs)


def report(label, ref, t, xs, p, exact):
    E = np.array([ref.energy(ti, xi, p) for ti, xi in zip(t, xs, strict=True)])
    viol = max(np.abs(ref.violation(ti, xi, p)).max() for ti, xi in zip(t, xs, strict=True))
    th, w = exact(t, xs[0, 0], xs[0, xs.shape[1] // 2])
    n = xs.shape[1] // 2
    pos = max(np.abs(np.cos(xs[:, 0]) - np.cos(th)).max(), np.abs(np.sin(xs[:, 0]) - np.sin(th)).max())
    vel = max(
        np.abs(-np.sin(xs[:, 0]) * xs[:, n] + np.sin(th) * w).max(),
        np.abs(np.cos(xs[:, 0]) * xs[:, n] - np.cos(th) * w).max(),
    )
    print(f"{label:58s} B0 pos {pos:9.2e}  vel {vel:9.2e}  |dE| {np.abs(E - E[0]).max():9.2e}  |viol| {viol:9.2e}")


def cost(repeats=200):
    md = iftomm_a02.model(40)
    ref = ReferenceKernel(derive(md))
    st = iftomm_a02.initial_state(40, theta0=0.7)
    x = np.array([st[str(v)] for v in md.q + md.u])
    Q, P, J, b, s = ref._terms(0.0, x, np.array([1.0, 1.0, 9.81]))
    c = -b + s
    n, m = Q.shape[0], J.shape[0]
    print(f"\ncost of one solve at n = {n}, m = {m} (numpy/LAPACK, median of {repeats}):")

    def paper():
        lu = sla.lu_factor(J[:, 1:])
        A_ = -sla.lu_solve(lu, J[:, :1])
        B_ = sla.lu_solve(lu, c)
        A2 = np.hstack([np.eye(1), A_.T])
        T = np.vstack([np.hstack([-A_, np.eye(m)]), A2 @ Q])
        return sla.lu_solve(sla.lu_factor(T), np.concatenate([B_, A2 @ P]))

    def qr_lapack():  # the chosen algorithm, LAPACK's geqp3 in place of the hand loop
        L = np.linalg.cholesky(Q)
        a = sla.solve_triangular(L, P, lower=True)
        K = sla.solve_triangular(L, J.T, lower=True)
        Z, R, piv = sla.qr(K, mode="economic", pivoting=True)
        y = sla.solve_triangular(R.T, (c - K.T @ a)[piv], lower=True)
        return sla.solve_triangular(L.T, a + Z @ y, lower=False)

    for name, fn in [
        ("paper T u̇ = V̂ (LU of J2, LU of T)", paper),
        ("gauss-qr (Cholesky + QRCP, LAPACK)", qr_lapack),
        ("gauss-normal (Cholesky + eigh of J Q⁻¹ Jᵀ)", lambda: gauss_normal(Q, P, J, c)),
        ("augmented-lagrangian (Cholesky of Q + αJᵀJ, iterated)", lambda: augmented_lagrangian(Q, P, J, c)),
    ]:
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        print(f"  {name:58s} {np.median(times) * 1e6:8.0f} µs")
    flops = {
        "paper 2/3 m³ + 2/3 n³ + n²m": 2 / 3 * m**3 + 2 / 3 * n**3 + n * n * m,
        "gauss-qr n³/3 + n²m + 2nm² − 2/3 m³": n**3 / 3 + n * n * m + 2 * n * m * m - 2 / 3 * m**3,
        "gauss-normal n³/3 + n²m + nm² + ~9 m³": n**3 / 3 + n * n * m + n * m * m + 9 * m**3,
        "AL n²m + n³/3 + k(2n² + 2nm), k = 3": n * n * m + n**3 / 3 + 3 * (2 * n * n + 2 * n * m),
    }
    print("  flops: " + ";  ".join(f"{k} ≈ {v:.2g}" for k, v in flops.items()))


def sweep():
    """The solves at states on the parallelogram branch ever closer to the horizontal position
    (θ → 0): error of θ̈ against the exact I θ̈ = −K cos θ, exactly on the branch and with the
    couplers' rates off it by 1e-10 rad/s (what integration leaves)."""
    N = 2
    p = np.array([1.0, 1.0, 9.81])
    inertia, K = iftomm_a02.pendulum_constants(N)
    E = 0.5 * inertia + K  # the benchmark's energy (vertical start, 1 rad/s)
    for coords in ("absolute", "relative"):
        md = iftomm_a02.model(N, coordinates=coords)
        ref = ReferenceKernel(derive(md))
        print(
            f"\nA02 N=2 ({coords} angles), |θ̈ − exact| at θ from the horizontal (on the branch / "
            "speeds off it by 1e-10):"
        )
        print("  θ        " + "".join(f"{h:>34s}" for h in ("paper", *CANDIDATES)))
        _sweep_rows(md, ref, p, inertia, K, E, coords)


def _sweep_rows(md, ref, p, inertia, K, E, coords):
    N = 2
    for th in (1e-1, 1e-3, 1e-5, 1e-7, 1e-9, 1e-11, 0.0):
        w = -np.sqrt(2 * (E - K * np.sin(th)) / inertia)
        row = []
        for off in (0.0, 1e-10):
            if coords == "absolute":
                x = np.array([th] * (N + 1) + [0.0] * N + [w] * (N + 1) + [off] * N)
            else:
                st = iftomm_a02.relative_state(N, theta0=th if th else 1e-300)
                x = np.array([st[str(v)] for v in md.q] + [w, -w + off, w, -w + off, w])
            exact = -K / inertia * np.cos(th)
            errs = []
            for how in ("paper", *CANDIDATES):
                try:
                    if how == "paper":
                        u = ref.rhs(0.0, x, p)[2 * N + 1 :]
                    else:
                        Q, P, J, b, s_ = ref._terms(0.0, x, p)
                        u = CANDIDATES[how](Q, P, J, -b + s_, max_rank=2 * N)
                    errs.append(abs(u[0] - exact))
                except Exception:
                    errs.append(np.nan)
            row.append(errs)
        cells = "".join(f"{a:>16.2e} /{b:>15.2e}" for a, b in zip(row[0], row[1], strict=True))
        print(f"  {th:7.0e}  {cells}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--t-final", type=float, default=2.0)
    ap.add_argument("--dt", type=float, default=1e-3)
    ap.add_argument("--cost", action="store_true", help="also time one solve at n = 81 (with --t-final 0: only that)")
    ap.add_argument("--only", default="")
    ap.add_argument("--sweep", action="store_true", help="only the solves near the singular position")
    args = ap.parse_args()
    if args.sweep:
        sweep()
        return
    if args.cost and args.t_final == 0:
        cost()
        return
    nsteps = round(args.t_final / args.dt)
    p = np.array([1.0, 1.0, 9.81])
    cases = []
    md = iftomm_a02.model(2)
    ref = ReferenceKernel(derive(md))
    st = iftomm_a02.initial_state(2)
    x0 = np.array([st[str(v)] for v in md.q + md.u])

    def ex_a02(t, th0, w0):
        return iftomm_a02.exact_motion(t, 2, th0, w0)

    cases.append(("A02 N=2", ref, x0, 4, ex_a02, ["paper", *CANDIDATES]))
    mdp = iftomm_a04.parallelogram_model(redundant=True)
    refp = ReferenceKernel(derive(mdp))
    stp = iftomm_a04.parallelogram_state()
    x0p = np.array([stp[str(v)] for v in mdp.q + mdp.u])
    I, K = iftomm_a04.parallelogram_constants()

    def ex_par(t, th0, w0):
        from scipy.integrate import solve_ivp

        sol = solve_ivp(
            lambda _t, y: [y[1], -K / I * np.cos(y[0])], (0, t[-1]), [th0, w0], "DOP853", t, rtol=1e-13, atol=1e-13
        )
        return sol.y

    cases.append(("redundant parallelogram", refp, x0p, 4, ex_par, ["paper", *CANDIDATES]))
    print(f"Kutta–Merson, dt = {args.dt}, {args.t_final} s, Γ1 = −20, Γ2 = −100")
    for label, r, x0_, mh, exact, hows in cases:
        G1, G2 = -20 * np.eye(mh), -100 * np.eye(mh)
        for how in hows:
            if args.only and args.only not in how:
                continue
            for project in (False, True):
                r.reset()
                t0 = time.perf_counter()
                status, t, xs = run(r, x0_, p, args.dt, nsteps, G1, G2, how, project)
                wall = time.perf_counter() - t0
                tag = f"{label}: {how}{' + projection' if project else ''} [{status}, {wall:.0f} s]"
                if len(t) > 1:
                    report(tag, r, t, xs, p, exact)
                else:
                    print(tag)
    if args.cost:
        cost()


if __name__ == "__main__":
    main()
