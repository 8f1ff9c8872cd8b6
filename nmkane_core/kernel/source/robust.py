# ruff: noqa: F821
"""Generic compiled kernel, part 4: the rank-robust constraint solve (docs/closed-loops.md §2, §7).

Not imported: :mod:`nmkane_core.kernel.codegen` appends this source to every generated kernel,
but only kernels generated with ``ROBUST = True`` call it (models with redundant equations,
without a declared partition, or declared to pass singular positions); numba prunes the
``if ROBUST:`` branches of every other kernel before compiling, so the paper's systems compile
and run exactly as before.  The numpy specification is :mod:`nmkane_core.symbolic.robust`.

Where J2 of the current partition is well-conditioned the paper's T u̇ = V̂ is solved as in
``rhs_ws`` (block elimination on A1's identity block), with the partition a run-time column
order of J (``w[OORD]``).  Its condition is measured scale-free, as
:func:`~nmkane_core.symbolic.robust.partition_rcond`: the smallest LU pivot of J2 after each
row of J = [J1 J2] is divided by its largest entry (0 where a whole row vanishes).  Below the
threshold ``solve = 2`` ("auto") re-picks the partition by Gaussian elimination with complete
pivoting on the equilibrated J (Wehage & Haug 1982) and, where no partition is
well-conditioned (J has lost rank, or the equations are redundant), solves Gauss's principle
in the mass metric: Q = L Lᵀ, K = L⁻¹Jᵀ with its columns equilibrated, Householder QR with
column pivoting stopped at the rank (at most ``max_rank`` steps), u̇ = L⁻ᵀ(â + Z_r y).
The dimensions reach the heavy routines as run-time values (``zero + N``): their loops then
compile compact instead of unrolled.

The solve's settings and state live in the work array at ``w[OSV + SV_*]``; the loops copy
their arguments there (:func:`solve_setup`) and read back the partition and what changed
(:func:`_log_solve`, the ``solve_log`` rows of :mod:`nmkane_core.kernel.constants`).
"""

import math

from numba import njit

# the solve's settings and state, at w[OSV + SV_*]
SV_MODE = 0  # asked for: 0 the paper's solve, 1 rank-robust, 2 auto
SV_RANK_TOL = 1
SV_MAX_RANK = 2
SV_CONSISTENCY_TOL = 3
SV_RCOND_ROBUST = 4
SV_RCOND_MIN = 5
SV_USED = 6  # what the last evaluation used: 0 the paper's solve (w[OORD]), 1 robust, −1 none yet
SV_CHANGED = 7  # 1.0: the last evaluation changed the solve or the partition
SV_STATUS = 8  # 0 ok, 1 Q not positive definite, 2 J u̇ = c inconsistent
SV_RANK = 9  # rank found by the last robust solve
SV_RESIDUAL = 10  # relative residual of the equations it dropped
SV_PIVOT = 11  # its smallest kept pivot
SV_ESTIMATE = 12  # the J2 estimate of the partition left (or taken)
SV_FORCES = 13  # 1.0: the robust solve has put F_c and λ into w (with OFLAG)
SV_LEAVE = 14  # kinetic-energy share of the last projection's speed correction
SV_STAB = 15  # u̇_sᵀQu̇_s / uᵀQu of the last evaluation: u̇_s the Baumgarte terms' part of u̇ (per step: × h²)
SV_FADE = 16  # 1.0: the Baumgarte terms of vanishing rows fade (a loop with a projection, solve auto or robust)


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _solve_defaults(w):
    """The settings a work array starts with (``make_workspace``): auto, the codegen's
    defaults, the kernel's own column order, nothing used yet."""
    w[OSV + SV_MODE] = 2.0
    w[OSV + SV_RANK_TOL] = RANK_TOL_DEFAULT
    w[OSV + SV_MAX_RANK] = MAX_RANK_DEFAULT
    w[OSV + SV_CONSISTENCY_TOL] = CONSISTENCY_TOL_DEFAULT
    w[OSV + SV_RCOND_ROBUST] = RCOND_ROBUST_DEFAULT
    w[OSV + SV_RCOND_MIN] = 0.0
    w[OSV + SV_USED] = -1.0
    w[OSV + SV_FADE] = 0.0
    for i in range(N):
        w[OORD + i] = i


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def solve_setup(w, solve, rank_tol, max_rank, consistency_tol, rcond_robust, rcond_min, order, projected):
    """A loop's solve arguments into the work array; ``order`` = the column order [u_I, u_D]
    of J, then the solve in use (``SV_USED``); ``projected``: the loop projects each step onto
    the constraints, so that the Baumgarte terms of vanishing rows may fade (``SV_FADE``)."""
    w[OSV + SV_MODE] = solve
    w[OSV + SV_FADE] = 1.0 if projected and solve != 0 else 0.0
    w[OSV + SV_RANK_TOL] = rank_tol
    w[OSV + SV_MAX_RANK] = max_rank
    w[OSV + SV_CONSISTENCY_TOL] = consistency_tol
    w[OSV + SV_RCOND_ROBUST] = rcond_robust
    w[OSV + SV_RCOND_MIN] = rcond_min
    for i in range(N):
        w[OORD + i] = order[i]
    w[OSV + SV_USED] = order[N]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _log_solve(t, w, stats, order, solve_log):
    """After an evaluation that changed the solve (or found the constraints inconsistent): the
    partition and the solve in use back into ``order``, a record into ``solve_log`` (the last
    row is kept for an inconsistent stop), its count in stats[STATS_SOLVE_LOG]."""
    for i in range(N):
        order[i] = int(w[OORD + i])
    order[N] = int(w[OSV + SV_USED])
    cap = solve_log.shape[0]
    k = int(stats[STATS_SOLVE_LOG])
    stats[STATS_SOLVE_LOG] = k + 1
    bad = w[OSV + SV_STATUS] == 2.0
    if cap == 0 or (k >= cap and not bad):
        return
    r = min(k, cap - 1)
    solve_log[r, 0] = t
    width = solve_log.shape[1] - LOG_HEAD
    for j in range(width):
        solve_log[r, LOG_HEAD + j] = 0.0
    if w[OSV + SV_USED] == 0.0:
        solve_log[r, 1] = LOG_PAPER
        solve_log[r, 2] = w[ORC]
        solve_log[r, 3] = M
        for j in range(min(N, width)):
            solve_log[r, LOG_HEAD + j] = w[OORD + j]
    else:
        solve_log[r, 1] = LOG_INCONSISTENT if bad else LOG_ROBUST
        solve_log[r, 2] = w[OSV + SV_RESIDUAL] if bad else w[OSV + SV_ESTIMATE]
        solve_log[r, 3] = w[OSV + SV_RANK]
        for j in range(min(M, width)):
            solve_log[r, LOG_HEAD + j] = w[ODROP + j]


# ------------------------------------------------------------------ the right-hand side
@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _constraint_rhs(w, G, G1, G2, m):
    """c = −b + s, s = [Γφ; Γ1ψ̇ + Γ2ψ] (105), (112) at OCV (s at OSS), and the row norms |J_i|∞ at ORN;
    with SV_FADE, s faded on the rows that vanish (BAUMGARTE_FADE)."""
    for i in range(m):
        s = 0.0
        if i < MNH:
            for k in range(MNH):
                s += G[i, k] * w[OPHIN + k]
        else:
            ih = i - MNH
            for k in range(MH):
                s += G1[ih, k] * w[OPSID + k] + G2[ih, k] * w[OPSI + k]
        w[OCV + i] = -w[OB + i] + s
        w[OSS + i] = s
        big = 0.0
        for kk in range(JPTR[i], JPTR[i + 1]):  # the row's structural nonzeros (the rest are exact zeros)
            a = abs(w[OJ + i * N + JIDX[kk]])
            if a > big or not math.isfinite(a):
                big = a
        w[ORN + i] = big
    # with a projection (SV_FADE) the Baumgarte terms of rows whose gradient vanishes fade out
    # (BAUMGARTE_FADE): near a singular position they would ask accelerations of order Γψ/|J_i|,
    # and the projection keeps the positions on the constraints anyway
    if w[OSV + SV_FADE] == 0.0:
        return
    longest = 0.0
    for i in range(m):
        longest = max(longest, w[ORN + i])
    for i in range(m):
        share = w[ORN + i] / longest if longest > 0.0 else 1.0
        if share < BAUMGARTE_FADE:
            f = (share / BAUMGARTE_FADE) * (share / BAUMGARTE_FADE)
            w[OSS + i] *= f
            w[OCV + i] = -w[OB + i] + w[OSS + i]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _paper_ordered(w, K, row, oord, n, m):
    """The paper's solve for the partition whose column order is at ``oord``: J2 X = R with
    R = [−J1 | c | s], rows equilibrated, then T u̇ = V̂ by block elimination (as ``rhs_ws``; the
    Baumgarte terms' part of u̇ beside it, at OUS).  w[ORC] receives J2's estimate (smallest pivot
    of the equilibrated LU; 0 where a row of J vanishes); "auto" below its threshold returns 0
    without solving, else returns 1."""
    pi = n - m
    ld = pi + 2
    big = 0.0
    for i in range(m):
        big = max(big, w[ORN + i])
    vanishing = not big > 0.0
    for i in range(m):
        if not w[ORN + i] > w[OSV + SV_RANK_TOL] * big:
            vanishing = True
    for i in range(n):  # OPOS: each column's position in this order (_reduced_ordered uses it too)
        w[OPOS + int(w[oord + i])] = i
    rc = 0.0
    if not vanishing and math.isfinite(big):
        for i in range(m):  # J2 into OJE, −J1 into R: zeros, then J's structural nonzeros in place
            inv = 1.0 / w[ORN + i]
            for j in range(m):
                w[OJE + i * m + j] = 0.0
            for j in range(pi):
                w[OR + i * ld + j] = 0.0
            for kk in range(JPTR[i], JPTR[i + 1]):
                j = JIDX[kk]
                pos = int(w[OPOS + j])
                if pos >= pi:
                    w[OJE + i * m + pos - pi] = w[OJ + i * N + j] * inv
                else:
                    w[OR + i * ld + pos] = -w[OJ + i * N + j] * inv
            w[OR + i * ld + pi] = w[OCV + i] * inv
            w[OR + i * ld + pi + 1] = w[OSS + i] * inv
        if lu_solve_flat(w, n - n + OJE, m, n - n + OR, ld, m, ld) > 0.0:
            rc = 1.0
            for i in range(m):
                rc = min(rc, abs(w[OJE + i * m + i]))
    w[ORC] = rc
    thr = w[OSV + SV_RCOND_MIN]
    if w[OSV + SV_MODE] == 2.0:
        thr = max(thr, w[OSV + SV_RCOND_ROBUST])
        if not rc > thr:
            return 0
    if not rc > 0.0:  # the paper's solve asked for, J2 singular: no u̇ (the loops stop on the estimate)
        w[ORC + 1] = 0.0
        return 1
    if w[OFLAG] != 0.0:  # J2 as it is, for the multipliers (_forces_robust)
        for i in range(m):
            for j in range(m):
                w[OJ2C + i * m + j] = w[OJ + i * N + int(w[oord + pi + j])]
    _reduced_ordered(w, K, row, oord, n, m)
    return 1


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _reduced_ordered(w, K, row, oord, n, m):
    """``_reduced_solve`` for a run-time column order: (A2 Q A2ᵀ) u̇_I = A2 (P − Q_{·D} B̂),
    u̇_D = A u̇_I + B̂ (106), (111), indices through ``oord``; beside it (the second column of
    each right-hand side) the Baumgarte terms' part u̇_s (B̂ → J2⁻¹s, P → 0) into OUS."""
    pi = n - m
    ld = pi + 2
    # W = Q A2ᵀ with A2ᵀ = [I; A], and y = P − Q_{·D} B̂ (and −Q_{·D} J2⁻¹s), over Q's structural
    # nonzeros (QPTR, QIDX), each column's position from OPOS (_paper_ordered)
    for i in range(n):
        oi = int(w[oord + i])
        for r in range(pi):
            w[OW + i * pi + r] = 0.0
        acc = w[OP + oi]
        acc_s = 0.0
        for kk in range(QPTR[oi], QPTR[oi + 1]):
            j = QIDX[kk]
            q = w[OQ + oi * N + j]
            pos = int(w[OPOS + j])
            if pos < pi:
                w[OW + i * pi + pos] += q
            else:
                k = pos - pi
                for r in range(pi):
                    w[OW + i * pi + r] += q * w[OR + k * ld + r]
                acc -= q * w[OR + k * ld + pi]
                acc_s -= q * w[OR + k * ld + pi + 1]
        w[OY + 2 * i] = acc
        w[OY + 2 * i + 1] = acc_s
    for r in range(pi):  # A2 Q A2ᵀ
        for c in range(pi):
            acc = w[OW + r * pi + c]
            for k in range(m):
                acc += w[OR + k * ld + r] * w[OW + (pi + k) * pi + c]
            w[OMR + r * pi + c] = acc
    for r in range(pi):
        for c in range(2):
            acc = w[OY + 2 * r + c]
            for k in range(m):
                acc += w[OR + k * ld + r] * w[OY + 2 * (pi + k) + c]
            w[OUI + 2 * r + c] = acc
    two = n - n + 2
    w[ORC + 1] = lu_solve_flat(w, n - n + OMR, pi, n - n + OUI, two, pi, two)
    for r in range(pi):
        j = int(w[oord + r])
        K[row, N + PERM[j]] = w[OUI + 2 * r]
        w[OUS + j] = w[OUI + 2 * r + 1]
    for k in range(m):
        acc = w[OR + k * ld + pi]
        acc_s = w[OR + k * ld + pi + 1]
        for r in range(pi):
            acc += w[OR + k * ld + r] * w[OUI + 2 * r]
            acc_s += w[OR + k * ld + r] * w[OUI + 2 * r + 1]
        j = int(w[oord + pi + k])
        K[row, N + PERM[j]] = acc
        w[OUS + j] = acc_s


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _repick(w, n, m):
    """Wehage & Haug's partition: Gaussian elimination with complete pivoting on J with its rows
    equilibrated (a row shorter than the rank threshold times the longest is left out); the
    pivot columns are u_D.  The new column order (u_I ascending, then u_D ascending) goes to
    OORD2; returns the rank found (partition_by_pivoting)."""
    tol = w[OSV + SV_RANK_TOL]
    big = 0.0
    for i in range(m):
        big = max(big, w[ORN + i])
    for i in range(m):
        active = big > 0.0 and w[ORN + i] > tol * big
        w[OROWS + i] = 1.0 if active else 0.0
        inv = 1.0 / w[ORN + i] if active else 0.0
        for j in range(n):
            w[OJE + i * n + j] = w[OJ + i * N + j] * inv
    for j in range(n):
        w[ODX + j] = 1.0  # column still free
    rank = 0
    for _ in range(min(m, n)):
        best = 0.0
        ib = -1
        jb = -1
        for i in range(m):
            if w[OROWS + i] == 1.0:
                for j in range(n):
                    if w[ODX + j] == 1.0:
                        a = abs(w[OJE + i * n + j])
                        if a > best:
                            best = a
                            ib = i
                            jb = j
        if ib < 0 or not best > tol:
            break
        piv = w[OJE + ib * n + jb]
        for i in range(m):
            if w[OROWS + i] == 1.0 and i != ib:
                f = w[OJE + i * n + jb] / piv
                if f != 0.0:
                    for j in range(n):
                        if w[ODX + j] == 1.0:
                            w[OJE + i * n + j] -= f * w[OJE + ib * n + j]
        w[OROWS + ib] = 0.0
        w[ODX + jb] = 0.0
        rank += 1
    pos = 0
    for j in range(n):  # u_I first, then u_D, each ascending
        if w[ODX + j] == 1.0:
            w[OORD2 + pos] = j
            pos += 1
    for j in range(n):
        if w[ODX + j] == 0.0:
            w[OORD2 + pos] = j
            pos += 1
    return rank


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _robust_rhs(w, K, row, n, m):
    """Gauss's principle in the mass metric (robust_solve): u̇ into K[row]; with OFLAG set, F_c
    and λ (the basic solution: 0 on the dropped equations) into OFC, OLAM."""
    if _chol(w, n - n + OQ, n - n + OLL, n) == 0:
        w[OSV + SV_STATUS] = 1.0
        w[ORC + 1] = 0.0
        for i in range(N):
            K[row, N + i] = 0.0
        return
    for i in range(n):  # â = L⁻¹P, K = L⁻¹Jᵀ
        w[OAH + i] = w[OP + i]
        for col in range(m):
            w[OKK + i * m + col] = w[OJ + col * N + i]
    one = n - n + 1
    _fwd(w, n - n + OLL, n, n - n + OAH, one)
    _fwd(w, n - n + OLL, n, n - n + OKK, m)
    scale = 1e-300
    for col in range(m):  # e = c − Kᵀâ
        ka = 0.0
        for i in range(n):
            ka += w[OKK + i * m + col] * w[OAH + i]
        w[OEE + col] = w[OCV + col] - ka
        scale = max(scale, abs(w[OCV + col]), abs(ka))
    rank = _qr_min_norm(w, n - n + OKK, n, m, w[OSV + SV_RANK_TOL], int(w[OSV + SV_MAX_RANK]))
    w[OSV + SV_RANK] = rank
    w[OSV + SV_RESIDUAL] = w[OSV + SV_RESIDUAL] / scale
    if not w[OSV + SV_RESIDUAL] <= w[OSV + SV_CONSISTENCY_TOL]:
        w[OSV + SV_STATUS] = 2.0
    _robust_stab(w, n, m, rank)
    for i in range(n):  # u̇ = L⁻ᵀ(â + z)
        w[OZZ + i] += w[OAH + i]
    _bwd_t(w, n - n + OLL, n, n - n + OZZ)
    for i in range(n):
        K[row, N + PERM[i]] = w[OZZ + i]
    if w[OFLAG] != 0.0:
        for k in range(rank - 1, -1, -1):  # R11 λ̃ = y, in place
            s = w[OYY + k]
            for j in range(k + 1, rank):
                s -= w[OKK + k * m + int(w[OPIV + j])] * w[OYY + j]
            w[OYY + k] = s / w[OKK + k * m + int(w[OPIV + k])]
        for col in range(m):
            w[OLAM + col] = 0.0
        for k in range(rank):
            col = int(w[OPIV + k])
            w[OLAM + col] = w[OYY + k] / w[ONRM + col]
        w[OSV + SV_FORCES] = 1.0


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _robust_stab(w, n, m, rank):
    """|u̇_s|²_Q of the robust solve into w[OSV + SV_STAB] (to be divided by uᵀQu): u̇_s the part
    the Baumgarte terms s make, = L⁻ᵀ z_s with z_s = Z_r R11⁻ᵀ (D s)[piv] (so |u̇_s|_Q = |z_s|);
    the QR of ``_qr_min_norm`` is in OKK."""
    for k in range(rank):  # R11ᵀ y_s = D s, in place at OUS
        col = int(w[OPIV + k])
        acc = w[OSS + col] / w[ONRM + col]
        for i in range(k):
            acc -= w[OKK + i * m + col] * w[OUS + i]
        w[OUS + k] = acc / w[OKK + k * m + col]
    for i in range(rank, n):
        w[OUS + i] = 0.0
    for k in range(rank - 1, -1, -1):  # z_s = Z_r [y_s; 0]
        col = int(w[OPIV + k])
        d = w[OUS + k]
        for i in range(k + 1, n):
            d += w[OKK + i * m + col] * w[OUS + i]
        d *= w[OBETA + k]
        w[OUS + k] -= d
        for i in range(k + 1, n):
            w[OUS + i] -= d * w[OKK + i * m + col]
    acc = 0.0
    for i in range(n):
        acc += w[OUS + i] * w[OUS + i]
    w[OSV + SV_STAB] = acc


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _stab_share(x, w, paper):
    """u̇_sᵀQu̇_s / uᵀQu (0 at rest) into w[OSV + SV_STAB]: the Baumgarte terms' share of the
    kinetic energy, per h² of a step (u̇_s at OUS for the paper's solve; |u̇_s|²_Q already there
    for the robust one)."""
    ke = 0.0
    ds = 0.0
    for i in range(N):
        ui = x[N + PERM[i]]
        acc_u = 0.0
        acc_s = 0.0
        for kk in range(QPTR[i], QPTR[i + 1]):  # Q's structural nonzeros
            j = QIDX[kk]
            q = w[OQ + i * N + j]
            acc_u += q * x[N + PERM[j]]
            if paper:
                acc_s += q * w[OUS + j]
        ke += ui * acc_u
        if paper:
            ds += w[OUS + i] * acc_s
    if not paper:
        ds = w[OSV + SV_STAB]
    w[OSV + SV_STAB] = ds / ke if ke > 0.0 else 0.0


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _rhs_robust(t, x, p, G, G1, G2, K, row, w):
    """``rhs_ws`` of a kernel with the rank-robust solve: ẋ = [C u + D; u̇] into K[row] by the
    paper's solve with the current partition, another partition, or the robust solve (w[OSV])."""
    terms(t, x, p, w)  # INLINE: the generator pastes the body of ``terms`` here (small models)
    for i in range(N):
        K[row, i] = w[OQD + i]
    zero = row - row
    n = zero + N
    m = zero + M
    prev = w[OSV + SV_USED]
    w[OSV + SV_CHANGED] = 0.0
    w[OSV + SV_STATUS] = 0.0
    if w[OFLAG] != 0.0:  # this evaluation's forces are wanted (later ones leave SV_FORCES)
        _keep_for_forces(w)
        w[OSV + SV_FORCES] = 0.0
    w[ORC] = 1.0
    w[ORC + 1] = 1.0
    _constraint_rhs(w, G, G1, G2, m)
    used = 1.0
    if w[OSV + SV_MODE] != 1.0 and w[OSV + SV_MAX_RANK] == M and M <= N:
        used = 0.0
        if _paper_ordered(w, K, row, zero + OORD, n, m) == 0:  # auto: J2 ill-conditioned here
            used = 1.0
            w[OSV + SV_ESTIMATE] = w[ORC]
            if _repick(w, n, m) == m and _paper_ordered(w, K, row, zero + OORD2, n, m) == 1:
                used = 0.0
                for i in range(N):
                    if w[OORD + i] != w[OORD2 + i]:
                        w[OSV + SV_CHANGED] = 1.0
                    w[OORD + i] = w[OORD2 + i]
    if used == 1.0:
        w[ORC] = 1.0  # no J2 in this solve
        _robust_rhs(w, K, row, n, m)
    if w[ORC + 1] > 0.0 and w[OSV + SV_STATUS] == 0.0:
        _stab_share(x, w, used == 0.0)
    else:
        w[OSV + SV_STAB] = 0.0
    if prev >= 0.0 and used != prev:
        w[OSV + SV_CHANGED] = 1.0
    w[OSV + SV_USED] = used
    if w[OFLAG] != 0.0:  # the partition its J2 copy was taken in (a later stage may change it)
        for i in range(N):
            w[OORDC + i] = w[OORD + i]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _forces_robust(w, K, krow):
    """``_forces`` of a kernel with the rank-robust solve: F_c = Q u̇ − P (J's column order) and
    λ — from the robust solve, or from J2ᵀλ = (F_c)_D of the partition in use."""
    for r in range(N):
        acc = -w[OPC + r]
        for c in range(N):
            acc += w[OQC + r * N + c] * K[krow, N + PERM[c]]
        w[OFC + r] = acc
    if w[OSV + SV_FORCES] == 0.0 and M > 0 and M <= N:
        pi = N - M
        for i in range(M):  # J2ᵀ, in place
            for j in range(i + 1, M):
                a = w[OJ2C + i * M + j]
                w[OJ2C + i * M + j] = w[OJ2C + j * M + i]
                w[OJ2C + j * M + i] = a
        for a in range(M):
            w[OLAM + a] = w[OFC + int(w[OORDC + pi + a])]
        zero = krow - krow
        one, m = zero + 1, zero + M
        lu_solve_flat(w, zero + OJ2C, m, zero + OLAM, one, m, one)
