# ruff: noqa: F821
"""Generic compiled kernel, part 2: the post-step projections (Blajer 2002; Yoon, Howe &
Greenwood 1994) onto the constraint manifold.

Not imported: :mod:`nmkane_core.kernel.codegen` appends this source after
:mod:`nmkane_core.kernel.source.loops` in every generated kernel module (see that file for the
names the model-specific part defines: ``N, M, MNH, MH, PERM``, ``terms`` ..., and the scratch
layout ``PS_*`` / ``projection_layout`` made from :data:`nmkane_core.kernel.interface.PROJECTION_SCRATCH`).
:mod:`nmkane_core.integrate.projection` describes the options (``proj`` array layout).
"""

import numpy as np
from numba import njit


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def make_projection_scratch():
    return np.zeros(PS_SIZE)


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _weighted_correction(w, ps, mrows, metric, N, M, perm):
    """δ = W⁻¹Gᵀ (G W⁻¹ Gᵀ)⁻¹ r for G (mrows×n) and r stored at ps[PS_OG:].

    ``metric`` 0: W = I (Moore–Penrose); 1: the kinetic-energy metric for a speed
    correction, W = Q; 2: the same for a coordinate correction, W = C⁻ᵀ Q C⁻¹ (so
    W⁻¹ = C Q⁻¹ Cᵀ).  Needs Q (``terms``) and C (``positions``) in ``w`` when weighted.
    δ is left at ps[PS_OD:PS_OD + N]; returns the pivot-ratio rcond of G W⁻¹ Gᵀ.
    """
    # dimensions arrive as runtime values here (not the module constants): this cold path
    # then compiles to compact loops instead of fully unrolled ones.  Every integer passed
    # on is a runtime value too (``zero``, ``one``), never a literal: numba would compile
    # one copy of the callee per literal value.
    zero = N - N
    one = zero + 1
    _, PS_OY, PS_OZ, PS_OS, PS_OZR, PS_OD, PS_OG, _ = projection_layout(N, M)
    OR_ = PS_OG + mrows * N
    for i in range(N):
        for r in range(mrows):
            ps[PS_OY + i * mrows + r] = ps[PS_OG + r * N + i]  # Y = Gᵀ
    if metric > 0:
        for i in range(N):  # Q, model order
            for j in range(N):
                ps[perm[i] * N + perm[j]] = w[OQ + i * N + j]
        if metric == 2:
            for i in range(N):  # Z = Cᵀ Gᵀ
                for r in range(mrows):
                    acc = 0.0
                    for k in range(N):
                        acc += w[OC + k * N + i] * ps[PS_OY + k * mrows + r]
                    ps[PS_OZ + i * mrows + r] = acc
            lu_solve_flat(ps, zero, N, PS_OZ, mrows, N, mrows)  # Z = Q⁻¹Cᵀ Gᵀ
            for i in range(N):  # Y = C Z
                for r in range(mrows):
                    acc = 0.0
                    for k in range(N):
                        acc += w[OC + i * N + k] * ps[PS_OZ + k * mrows + r]
                    ps[PS_OY + i * mrows + r] = acc
        else:
            lu_solve_flat(ps, zero, N, PS_OY, mrows, N, mrows)  # Y = Q⁻¹Gᵀ
    for a in range(mrows):
        for b in range(mrows):
            acc = 0.0
            for i in range(N):
                acc += ps[PS_OG + a * N + i] * ps[PS_OY + i * mrows + b]
            ps[PS_OS + a * mrows + b] = acc
        ps[PS_OZR + a] = ps[OR_ + a]
    rc = lu_solve_flat(ps, PS_OS, mrows, PS_OZR, one, mrows, one)
    for i in range(N):
        acc = 0.0
        for a in range(mrows):
            acc += ps[PS_OY + i * mrows + a] * ps[PS_OZR + a]
        ps[PS_OD + i] = acc
    return rc


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def project(t, x, p, w, ps, proj, E0, viol, perm):
    """Post-step correction of positions, then speeds (geometric elimination): 0, or 1 when a
    correction matrix was singular.  Kernels with the rank-robust solve use its pseudo-inverse
    (``_project_robust`` in source/robust.py; 2: the motion left the constraints)."""
    if ROBUST:
        code = _project_robust(t, x, p, w, proj, E0, viol)
    else:
        code = _project_paper(t, x, p, w, ps, proj, E0, viol, perm)
    return code


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _project_paper(t, x, p, w, ps, proj, E0, viol, perm):
    """Post-step correction of positions, then speeds (geometric elimination).

    (P) ψ(q) = 0: q ← q − W⁻¹Ψ_qᵀ(Ψ_q W⁻¹ Ψ_qᵀ)⁻¹ψ, up to ``pos_iters`` Newton steps, the
        Jacobian updated each step (``newton``) or frozen at the uncorrected point;
    (V) [φ; ψ̇](q, u) = 0 at the corrected q: u ← u − W⁻¹Jᵀ(J W⁻¹ Jᵀ)⁻¹[φ; ψ̇], Newton in u
        (one step is exact for constraints linear in u; up to 3 for nonlinear ones);
    (E) optionally u ← λu with λ² = (E0 − E(q,0)) / (E(q,u) − E(q,0)), restoring the
        initial energy (keeps constraints homogeneous in u satisfied).
    Returns 0, or 1 when a correction matrix was singular.
    """
    weight, pos_iters, newton, energy_fix = proj[0], proj[1], proj[2], proj[3]
    N, M, MNH, MH = proj[4], proj[5], proj[6], proj[7]  # runtime values (see above)
    _, _, _, _, _, PS_OD, PS_OG, _ = projection_layout(N, M)
    tol = 1e-15
    if MH > 0:
        for it in range(pos_iters):
            positions(t, x, p, w)
            big = 0.0
            for a in range(MH):
                big = max(big, abs(w[OPSI + a]))
            if big <= tol:
                break
            if newton or it == 0:
                for a in range(MH):
                    for j in range(N):
                        ps[PS_OG + a * N + j] = w[OPSQ + a * N + j]
            for a in range(MH):
                ps[PS_OG + MH * N + a] = w[OPSI + a]
            if weight == 1:
                terms_call(t, x, p, w)
            if _weighted_correction(w, ps, MH, 2 * weight, N, M, perm) == 0.0:
                return 1
            for i in range(N):
                x[i] -= ps[PS_OD + i]
    if M > 0:
        for it in range(3):
            terms_call(t, x, p, w)
            big = 0.0
            for a in range(MNH):
                big = max(big, abs(w[OPHIN + a]))
            for a in range(MH):
                big = max(big, abs(w[OPSID + a]))
            if big <= tol:
                break
            for a in range(M):  # J = ∂[φ; ψ̇]/∂u in model column order
                for j in range(N):
                    ps[PS_OG + a * N + perm[j]] = w[OJ + a * N + j]
            for a in range(MNH):
                ps[PS_OG + M * N + a] = w[OPHIN + a]
            for a in range(MH):
                ps[PS_OG + M * N + MNH + a] = w[OPSID + a]
            if _weighted_correction(w, ps, M, weight, N, M, perm) == 0.0:
                return 1
            for i in range(N):
                x[N + i] -= ps[PS_OD + i]
    if energy_fix:
        for i in range(N):
            ps[PS_OD + i] = x[N + i]
            x[N + i] = 0.0
        V0 = diagnostics(t, x, p, viol)
        for i in range(N):
            x[N + i] = ps[PS_OD + i]
        K = diagnostics(t, x, p, viol) - V0
        if K > 0.0 and E0 > V0:
            lam = math.sqrt((E0 - V0) / K)
            for i in range(N):
                x[N + i] *= lam
    return 0


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def project_state(t, x, p, proj):
    """Project one state onto the constraint manifold (initial states); returns (x, code)."""
    w = make_workspace()
    ps = make_projection_scratch()
    perm = PERM.copy()
    viol = np.empty(NV)
    y = x.copy()
    code = project(t, y, p, w, ps, proj, 0.0, viol, perm)
    return y, code


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def project_state_robust(t, x, p, proj, max_rank):
    """``project_state`` with the rank of the model's constraints (kernels with ROBUST)."""
    w = make_workspace()
    if ROBUST:
        w[OSV + SV_MAX_RANK] = max_rank
    ps = make_projection_scratch()
    perm = PERM.copy()
    viol = np.empty(NV)
    y = x.copy()
    code = project(t, y, p, w, ps, proj, 0.0, viol, perm)
    return y, code
