# ruff: noqa: F821
"""Generic compiled kernel: the paper's numeric solve and the integrator loops.

This file is *not imported*.  :mod:`nmkane_core.codegen` appends its source to every
generated kernel module, after the model-specific part that defines the dimensions
``N, M, MNH, MH, PI, NV`` (n speeds, m constraints of which MNH nonholonomic and MH
holonomic, p = PI independent speeds, NV reported violations), the permutation ``PERM``
from [u_I, u_D] back to the model's speeds, and the straight-line functions ``terms`` and
``diagnostics``.  The integrators are tableau-driven (methods are data): one fixed-step
loop and one adaptive loop serve every explicit Runge–Kutta tableau.

Status codes returned by the loops:
    0 ok, 1 J2 ill-conditioned, 2 T ill-conditioned, 3 state not finite,
    4 step size underflow (adaptive), 5 step budget of this call used (adaptive).
"""

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def lu_solve_inplace(A, B):
    """Solve A X = B in place (LU, partial pivoting); B (n×k) receives X.

    Returns min|pivot|/max|pivot| (0 when singular): the reciprocal-condition estimate
    the kernels compare with the threshold ``rcond_min``.
    """
    n = A.shape[0]
    k = B.shape[1]
    pmax = 0.0
    pmin = np.inf
    for c in range(n):
        piv = c
        big = abs(A[c, c])
        for i in range(c + 1, n):
            v = abs(A[i, c])
            if v > big:
                big = v
                piv = i
        if not (big > 0.0):          # zero or NaN pivot
            return 0.0
        if piv != c:
            for j in range(n):
                tmp = A[c, j]
                A[c, j] = A[piv, j]
                A[piv, j] = tmp
            for j in range(k):
                tmp = B[c, j]
                B[c, j] = B[piv, j]
                B[piv, j] = tmp
        if big > pmax:
            pmax = big
        if big < pmin:
            pmin = big
        inv = 1.0 / A[c, c]
        for i in range(c + 1, n):
            f = A[i, c] * inv
            if f != 0.0:
                for j in range(c + 1, n):
                    A[i, j] -= f * A[c, j]
                for j in range(k):
                    B[i, j] -= f * B[c, j]
    for c in range(n - 1, -1, -1):
        inv = 1.0 / A[c, c]
        for j in range(k):
            acc = B[c, j]
            for l in range(c + 1, n):
                acc -= A[c, l] * B[l, j]
            B[c, j] = acc * inv
    if n == 0:
        return 1.0
    return pmin / pmax


@njit(cache=True, nogil=True)
def make_workspace():
    """Scratch arrays of one right-hand side evaluation (allocated once per run)."""
    J = np.empty((M, N))
    b = np.empty(M)
    phin = np.empty(MNH)
    psid = np.empty(MH)
    psi = np.empty(MH)
    Q = np.empty((N, N))
    P = np.empty(N)
    qdot = np.empty(N)
    R = np.empty((M, PI + 1))
    T = np.empty((N, N))
    V = np.empty((N, 1))
    rc = np.ones(2)
    return J, b, phin, psid, psi, Q, P, qdot, R, T, V, rc


@njit(cache=True, nogil=True)
def rhs_ws(t, x, p, G, G1, G2, xdot, ws):
    """ẋ = [C u + D; T⁻¹V̂] into ``xdot``; ws[-1] receives (rcond J2, rcond T)."""
    J, b, phin, psid, psi, Q, P, qdot, R, T, V, rc = ws
    terms(t, x, p, J, b, phin, psid, psi, Q, P, qdot)
    for i in range(N):
        xdot[i] = qdot[i]
    rc[0] = 1.0
    if M > 0:
        # R = [−J1 | −b + s], s = [Γφ; Γ1ψ̇ + Γ2ψ]   (105), (112)
        for i in range(M):
            for j in range(PI):
                R[i, j] = -J[i, j]
            s = 0.0
            if i < MNH:
                for k in range(MNH):
                    s += G[i, k] * phin[k]
            else:
                ih = i - MNH
                for k in range(MH):
                    s += G1[ih, k] * psid[k] + G2[ih, k] * psi[k]
            R[i, PI] = -b[i] + s
        # J2 X = R  ->  X = [A | B̂]   (20), (108), (113)
        rc[0] = lu_solve_inplace(J[:, PI:], R)
        if rc[0] == 0.0:
            rc[1] = 0.0
            return
        # T = [A1; A2 Q], V̂ = [B̂; A2 P]   (22), (40), (44), (110)
        for i in range(M):
            for j in range(PI):
                T[i, j] = -R[i, j]
            for j in range(M):
                T[i, PI + j] = 1.0 if i == j else 0.0
            V[i, 0] = R[i, PI]
        for r in range(PI):
            for j in range(N):
                acc = Q[r, j]
                for k in range(M):
                    acc += R[k, r] * Q[PI + k, j]
                T[M + r, j] = acc
            acc = P[r]
            for k in range(M):
                acc += R[k, r] * P[PI + k]
            V[M + r, 0] = acc
    else:
        for i in range(N):
            for j in range(N):
                T[i, j] = Q[i, j]
            V[i, 0] = P[i]
    rc[1] = lu_solve_inplace(T, V)                  # (111) T u̇ = V̂
    for i in range(N):
        xdot[N + PERM[i]] = V[i, 0]


@njit(cache=True, nogil=True)
def rhs(t, x, p, G, G1, G2):
    """Convenience form for Python callers and tests: returns (ẋ, rcond J2, rcond T)."""
    ws = make_workspace()
    xdot = np.empty(2 * N)
    rhs_ws(t, x, p, G, G1, G2, xdot, ws)
    return xdot, ws[11][0], ws[11][1]


@njit(cache=True, nogil=True)
def _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, ws, rcond_min, rcmin):
    """Fill the stage derivatives K[i] of one explicit RK step; return a status code."""
    S = TC.shape[0]
    n2 = 2 * N
    rc = ws[11]
    for i in range(S):
        total = 0.0
        for j in range(n2):
            acc = x[j]
            for l in range(i):
                a = TA[i, l]
                if a != 0.0:
                    acc += h * a * K[l, j]
            xs[j] = acc
            total += abs(acc)
        if not math.isfinite(total):      # a stage left the finite numbers: divergence
            return 3
        rhs_ws(t + TC[i] * h, xs, p, G, G1, G2, K[i], ws)
        if rc[0] < rcmin[0]:
            rcmin[0] = rc[0]
        if rc[1] < rcmin[1]:
            rcmin[1] = rc[1]
        if rc[0] <= rcond_min:
            return 1
        if rc[1] <= rcond_min:
            return 2
    return 0


@njit(cache=True, nogil=True)
def _record(t, x, p, viol, stats, nv):
    """Diagnostics of an accepted state; running maxima in ``stats``. Returns E, or NaN."""
    E = diagnostics(t, x, p, viol)
    dE = E - stats[0]
    if abs(dE) > stats[1]:
        stats[1] = abs(dE)
    stats[2] = dE
    for i in range(nv):
        v = abs(viol[i])
        if v > stats[STATS_FIXED + i]:
            stats[STATS_FIXED + i] = v
        if not math.isfinite(v):
            return np.nan
    return E


STATS_FIXED = 5   # stats = [E0, max|ΔE|, last ΔE, min rcond J2, min rcond T, max|viol_i|...]


@njit(cache=True, nogil=True)
def integrate_fixed(x, t0, dt, t_final, k0, k1, nsteps, every, p, G, G1, G2, TA, TB, TC,
                    rcond_min, out_t, out_x, out_E, out_V, row, stats):
    """Steps k0 … k1−1 of a fixed-step run of ``nsteps`` steps; ``x`` is advanced in place.

    Row r of the outputs holds the state after step r·every (and the final state).
    Returns (status, steps done so far, next free row).
    """
    S = TC.shape[0]
    n2 = 2 * N
    K = np.empty((S, n2))
    xs = np.empty(n2)
    xn = np.empty(n2)
    viol = np.empty(NV)
    ws = make_workspace()
    rcmin = stats[3:5]
    for k in range(k0, k1):
        t = t0 + k * dt
        h = dt if k < nsteps - 1 else t_final - t
        code = _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, ws, rcond_min, rcmin)
        if code != 0:
            return code, k, row
        finite = True
        for j in range(n2):
            acc = 0.0
            for i in range(S):
                acc += TB[i] * K[i, j]
            xn[j] = x[j] + h * acc
            if not math.isfinite(xn[j]):
                finite = False
        if not finite:
            return 3, k, row
        tn = t0 + (k + 1) * dt if k < nsteps - 1 else t_final
        E = _record(tn, xn, p, viol, stats, NV)
        if not math.isfinite(E):
            return 3, k, row
        for j in range(n2):
            x[j] = xn[j]
        if (k + 1) % every == 0 or k + 1 == nsteps:
            out_t[row] = tn
            for j in range(n2):
                out_x[row, j] = x[j]
            out_E[row] = E
            for j in range(NV):
                out_V[row, j] = viol[j]
            row += 1
    return 0, k1, row


@njit(cache=True, nogil=True)
def integrate_adaptive(x, t, t_final, h, rtol, atol, hmin, hmax, max_steps, every, accepted,
                       p, G, G1, G2, TA, TB, TE, TC, err_exp, rcond_min,
                       out_t, out_x, out_E, out_V, stats):
    """Adaptive embedded-RK run from t until t_final, the output buffer is full, or
    ``max_steps`` attempts; error = h Σ TE_i K_i, step control with exponent ``err_exp``.

    Returns (status, t, h, rows written, accepted steps, attempted steps).
    """
    S = TC.shape[0]
    n2 = 2 * N
    K = np.empty((S, n2))
    xs = np.empty(n2)
    xn = np.empty(n2)
    viol = np.empty(NV)
    ws = make_workspace()
    rcmin = stats[3:5]
    cap = out_t.shape[0]
    row = 0
    attempts = 0
    while t < t_final and row < cap:
        if attempts >= max_steps:
            return 5, t, h, row, accepted, attempts
        attempts += 1
        last = False
        if t + h >= t_final or (t_final - t - h) < 1e-12 * abs(t_final):
            h = t_final - t
            last = True
        code = _stages(t, h, x, p, G, G1, G2, TA, TC, K, xs, ws, rcond_min, rcmin)
        if code != 0:
            return code, t, h, row, accepted, attempts
        errsum = 0.0
        finite = True
        for j in range(n2):
            acc = 0.0
            accE = 0.0
            for i in range(S):
                acc += TB[i] * K[i, j]
                accE += TE[i] * K[i, j]
            xn[j] = x[j] + h * acc
            if not math.isfinite(xn[j]):
                finite = False
            sc = atol + rtol * max(abs(x[j]), abs(xn[j]))
            e = h * accE / sc
            errsum += e * e
        err = math.sqrt(errsum / n2) if finite else np.inf
        if err <= 1.0:
            tn = t_final if last else t + h
            E = _record(tn, xn, p, viol, stats, NV)
            if not math.isfinite(E):
                return 3, t, h, row, accepted, attempts
            t = tn
            for j in range(n2):
                x[j] = xn[j]
            accepted += 1
            if accepted % every == 0 or t >= t_final:
                out_t[row] = t
                for j in range(n2):
                    out_x[row, j] = x[j]
                out_E[row] = E
                for j in range(NV):
                    out_V[row, j] = viol[j]
                row += 1
            fac = 5.0 if err == 0.0 else min(5.0, max(0.2, 0.9 * err ** (-err_exp)))
        else:
            fac = 0.2 if not math.isfinite(err) else max(0.2, 0.9 * err ** (-err_exp))
        h = min(h * fac, hmax)
        if h < hmin and t < t_final:
            return 4, t, h, row, accepted, attempts
    return 0, t, h, row, accepted, attempts


@njit(cache=True, nogil=True)
def diagnostics_rows(ts, xs, p, E, V):
    """Energy and violations of many states (scipy adapter, initial row)."""
    viol = np.empty(NV)
    for r in range(ts.shape[0]):
        E[r] = diagnostics(ts[r], xs[r], p, viol)
        for j in range(NV):
            V[r, j] = viol[j]


@njit(cache=True, nogil=True)
def outputs_rows(ts, xs, p, O):
    out = np.empty(NO)
    for r in range(ts.shape[0]):
        outputs(ts[r], xs[r], p, out)
        for j in range(NO):
            O[r, j] = out[j]


@njit(cache=True, nogil=True)
def constraint_terms(t, x, p):
    """(J, b, φ, ψ̇, ψ) at a state, for state completion and projections."""
    J, b, phin, psid, psi, Q, P, qdot, R, T, V, rc = make_workspace()
    terms(t, x, p, J, b, phin, psid, psi, Q, P, qdot)
    return J, b, phin, psid, psi
