# ruff: noqa: F821
"""Generic compiled kernel, part 4c: the rank-robust solve's post-step projections (the smallest
correction in the projection's metric on the independent rows) and the adaptive steps' error
estimate on the tangent space.  Not imported: appended to every generated kernel
(:mod:`nmkane_core.kernel.codegen`)."""

import math

from numba import njit


# ------------------------------------------------------------------ projections and the tangent space
@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _model_q(w, n):
    """Q in the model's speed order at OQM (the projections work in the model's order)."""
    for i in range(n):
        for j in range(n):
            w[OQM + PERM[i] * n + PERM[j]] = w[OQ + i * N + j]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _correction(w, n, mrows, og, weighted, with_c, cap):
    """δ = B z with z the smallest solution of (G B)z = e on the independent rows — the smallest
    correction in the metric W = (B Bᵀ)⁻¹ with G δ = e (the robust pseudo-inverse of the
    projections, ``robust_solve(W, 0, G, e)``): B = I, or L⁻ᵀ with L at OLL (W = Q), or
    C L⁻ᵀ (W = C⁻ᵀQC⁻¹, ``with_c``).  G (mrows×n, model order) at ``og``, e at OEE; δ at OZZ."""
    for i in range(n):  # K = Bᵀ Gᵀ
        for a in range(mrows):
            if with_c:
                acc = 0.0
                for k in range(n):
                    acc += w[OC + k * n + i] * w[og + a * n + k]
            else:
                acc = w[og + a * n + i]
            w[OKK + i * mrows + a] = acc
    zero = n - n
    if weighted:
        _fwd(w, zero + OLL, n, zero + OKK, mrows)
    rank = _qr_min_norm(w, zero + OKK, n, mrows, w[OSV + SV_RANK_TOL], cap)
    if weighted:
        _bwd_t(w, zero + OLL, n, zero + OZZ)
    if with_c:
        for i in range(n):
            w[OAH + i] = w[OZZ + i]
        for i in range(n):
            acc = 0.0
            for k in range(n):
                acc += w[OC + i * n + k] * w[OAH + k]
            w[OZZ + i] = acc
    return rank


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _speed_rows(w, n, m):
    """J = ∂[φ; ψ̇]/∂u in the model's speed order at OJE (``terms`` has run)."""
    for a in range(m):
        for j in range(n):
            w[OJE + a * n + PERM[j]] = w[OJ + a * N + j]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _project_robust(t, x, p, w, proj, E0, viol):
    """``project`` with the robust pseudo-inverse (redundant equations and singular positions
    need nothing else): positions by Newton steps δq = −W⁻¹ψ_qᵀ(ψ_q W⁻¹ψ_qᵀ)⁺ψ, speeds by
    δu = −Q⁻¹Jᵀ(J Q⁻¹Jᵀ)⁺[φ; ψ̇] (``proj[0]``: 1 the mass metric, 0 the identity), each capped at
    the model's rank.  Returns 0; 1 when Q is not positive definite; 2 when the first speed
    correction carries more than ROBUST_LEAVE_KE of the kinetic energy (the motion left the
    constraints: w[OSV + SV_LEAVE] holds the share)."""
    weight, pos_iters, newton, energy_fix = proj[0], proj[1], proj[2], proj[3]
    zero = proj[4] - proj[4]
    n, m, mh = zero + N, zero + M, zero + MH
    cap = int(w[OSV + SV_MAX_RANK])
    with_c = weight == 1 and not C_IS_I
    tol = 1e-15
    for it in range(pos_iters if MH > 0 else 0):
        positions(t, x, p, w)
        big = 0.0
        for a in range(MH):
            big = max(big, abs(w[OPSI + a]))
        if big <= tol:
            break
        if weight == 1:
            terms_call(t, x, p, w)
            _model_q(w, n)
            if _chol(w, zero + OQM, zero + OLL, n) == 0:
                return 1
        og = zero + OPSQ
        if newton == 0:  # simplified Newton: the Jacobian of the uncorrected point
            og = zero + OJE
            if it == 0:
                for k in range(MH * N):
                    w[OJE + k] = w[OPSQ + k]
        for a in range(MH):
            w[OEE + a] = -w[OPSI + a]
        _correction(w, n, mh, og, weight == 1, with_c, cap if MNH == 0 else mh)
        for i in range(N):
            x[i] += w[OZZ + i]
    leave = 0.0
    for it in range(3):
        terms_call(t, x, p, w)
        big = 0.0
        for a in range(MNH):
            big = max(big, abs(w[OPHIN + a]))
        for a in range(MH):
            big = max(big, abs(w[OPSID + a]))
        if big <= tol:
            break
        _model_q(w, n)
        pd = _chol(w, zero + OQM, zero + OLL, n)
        if weight == 1 and pd == 0:
            return 1
        _speed_rows(w, n, m)
        for a in range(MNH):
            w[OEE + a] = -w[OPHIN + a]
        for a in range(MH):
            w[OEE + MNH + a] = -w[OPSID + a]
        _correction(w, n, m, zero + OJE, weight == 1, False, cap)
        if it == 0:  # the correction's share of the kinetic energy: δuᵀQδu / uᵀQu
            dke, ke = 0.0, 0.0
            for i in range(N):
                for j in range(N):
                    q = w[OQM + i * N + j]
                    dke += w[OZZ + i] * q * w[OZZ + j]
                    ke += x[N + i] * q * x[N + j]
            if dke > 0.0:
                leave = dke / ke if ke > 0.0 else math.inf
        for i in range(N):
            x[N + i] += w[OZZ + i]
    w[OSV + SV_LEAVE] = leave
    if leave > ROBUST_LEAVE_KE:
        return 2
    if energy_fix:
        for i in range(N):
            w[OAH + i] = x[N + i]
            x[N + i] = 0.0
        V0 = diagnostics(t, x, p, viol)
        for i in range(N):
            x[N + i] = w[OAH + i]
        kin = diagnostics(t, x, p, viol) - V0
        if kin > 0.0 and E0 > V0:
            lam = math.sqrt((E0 - V0) / kin)
            for i in range(N):
                x[N + i] *= lam
    return 0


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _tangent(t, x, p, w, proj):
    """The error estimate at w[ODX] (2N, model order) without its components along the
    constraint normals, in the projection's metric (ReferenceKernel.tangent): the part the
    post-step projection does not remove.  Near a singular position the estimate is dominated
    by those components (the branch's amplified asymmetry): an error control that sees them
    shrinks the step onto the singular point."""
    weight = proj[0]
    zero = proj[4] - proj[4]
    n, m, mh = zero + N, zero + M, zero + MH
    cap = int(w[OSV + SV_MAX_RANK])
    terms_call(t, x, p, w)
    _model_q(w, n)
    weighted = weight == 1 and _chol(w, zero + OQM, zero + OLL, n) == 1
    if MH > 0:
        positions(t, x, p, w)
        for a in range(MH):  # e = −ψ_q δq
            acc = 0.0
            for j in range(N):
                acc += w[OPSQ + a * N + j] * w[ODX + j]
            w[OEE + a] = -acc
        _correction(w, n, mh, zero + OPSQ, weighted, weighted and not C_IS_I, cap if MNH == 0 else mh)
        for i in range(N):
            w[ODX + i] += w[OZZ + i]
    _speed_rows(w, n, m)
    for a in range(M):  # e = −J δu
        acc = 0.0
        for j in range(N):
            acc += w[OJE + a * N + j] * w[ODX + N + j]
        w[OEE + a] = -acc
    _correction(w, n, m, zero + OJE, weighted, False, cap)
    for i in range(N):
        w[ODX + N + i] += w[OZZ + i]
