# ruff: noqa: F821
"""Generic compiled kernel, part 1b: the paper's numeric solve T u̇ = V̂ (block elimination on
A1's identity block, (20), (42)–(46)), its LU with the rcond estimate, and the multipliers
from J2ᵀλ = (F_c)_D.  Not imported: :mod:`nmkane_core.kernel.codegen` appends it to every
generated kernel with the other generic parts (names are the generated module's)."""

import math

from numba import njit


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def lu_solve_flat(w, oa, lda, ob, ldb, n, k):
    """Solve A X = B in place in the flat work array ``w`` (LU with partial pivoting).

    A is n×n at offset ``oa`` with row stride ``lda``; B is n×k at ``ob`` with row
    stride ``ldb`` and receives X.  Returns min|pivot|/max|pivot| (0 when singular): the
    reciprocal-condition estimate the kernels compare with ``rcond_min``.  One return, at
    the end, so that the right-hand side can inline it (``# INLINE``, kernel.inline.inline_marked);
    cold paths call it.
    """
    pmax = 0.0
    pmin = 1e308
    singular = False
    for c in range(n):
        piv = c
        big = abs(w[oa + c * lda + c])
        for i in range(c + 1, n):
            v = abs(w[oa + i * lda + c])
            if v > big:
                big = v
                piv = i
        if not (big > 0.0):  # zero or NaN pivot
            singular = True
            break
        if piv != c:
            for j in range(n):
                tmp = w[oa + c * lda + j]
                w[oa + c * lda + j] = w[oa + piv * lda + j]
                w[oa + piv * lda + j] = tmp
            for j in range(k):
                tmp = w[ob + c * ldb + j]
                w[ob + c * ldb + j] = w[ob + piv * ldb + j]
                w[ob + piv * ldb + j] = tmp
        if big > pmax:
            pmax = big
        if big < pmin:
            pmin = big
        hi = n  # one past the pivot row's last nonzero (BAND_MIN)
        if n > BAND_MIN:
            while hi > c + 1 and w[oa + c * lda + hi - 1] == 0.0:
                hi -= 1
        inv = 1.0 / w[oa + c * lda + c]
        for i in range(c + 1, n):
            f = w[oa + i * lda + c] * inv
            if f != 0.0:
                for j in range(c + 1, hi):
                    w[oa + i * lda + j] -= f * w[oa + c * lda + j]
                for j in range(k):
                    w[ob + i * ldb + j] -= f * w[ob + c * ldb + j]
    rc = 1.0
    if singular:
        rc = 0.0
    elif n > 0:
        for c in range(n - 1, -1, -1):
            hi = n  # U's row c ends there: the rest are zeros
            if n > BAND_MIN:
                while hi > c + 1 and w[oa + c * lda + hi - 1] == 0.0:
                    hi -= 1
            inv = 1.0 / w[oa + c * lda + c]
            for j in range(k):
                acc = w[ob + c * ldb + j]
                for l in range(c + 1, hi):
                    acc -= w[oa + c * lda + l] * w[ob + l * ldb + j]
                w[ob + c * ldb + j] = acc * inv
        rc = pmin / pmax
    return rc


#: matrices larger than this are treated as banded by ``lu_solve_flat``: each row's elimination
#: and back substitution stop at its last nonzero (a chain's J2 has a few entries a row near
#: the diagonal); the small matrices of most models keep the plain loops (where the size is a
#: constant of the kernel, numba drops the search)
BAND_MIN = 8


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _rhs_paper(t, x, p, G, G1, G2, K, row, w):
    """The paper's solve with the declared partition (pasted into ``rhs_ws``)."""
    terms(t, x, p, w)  # INLINE: the generator pastes the body of ``terms`` here (kernel.inline.inline_marked)
    for i in range(N):
        K[row, i] = w[OQD + i]
    w[ORC] = 1.0
    if w[OFLAG] != 0.0:  # this evaluation's forces are wanted: J2 before its LU, Q and P
        _keep_for_forces(w)
        for i in range(M):
            for j in range(M):
                w[OJ2C + i * M + j] = w[OJ + i * N + PI + j]
    if M > 0:
        # R = [−J1 | −b + s], s = [Γφ; Γ1ψ̇ + Γ2ψ]   (105), (112)
        for i in range(M):
            for j in range(PI):
                w[OR + i * (PI + 1) + j] = -w[OJ + i * N + j]
            s = 0.0
            if i < MNH:
                for k in range(MNH):
                    s += G[i, k] * w[OPHIN + k]
            else:
                ih = i - MNH
                for k in range(MH):
                    s += G1[ih, k] * w[OPSID + k] + G2[ih, k] * w[OPSI + k]
            w[OR + i * (PI + 1) + PI] = -w[OB + i] + s
        if SCALE_ROWS or NORM_ROWS:
            # rows of J (and R: same solution) scaled for the condition estimate (kernel_terms.row_degrees):
            # degree k > 1 in u: by 1/max(1, |u|∞)^(k−1); not polynomial (ROWDEG 0): by 1/max_j |J_ij|,
            # and the estimate is at most the row's share on u_D, max_j |J2_ij| / max_j |J_ij|
            un = 1.0
            for j in range(N):
                un = max(un, abs(x[N + j]))
            inv = 1.0 / un
            share = 1.0
            for i in range(M):
                sc = 1.0
                if ROWDEG[i] > 1:
                    sc = inv
                    for _ in range(ROWDEG[i] - 2):
                        sc *= inv
                elif ROWDEG[i] == 0:
                    big = 0.0
                    big_d = 0.0
                    for j in range(N):
                        a = abs(w[OJ + i * N + j])
                        if a > big:
                            big = a
                        if j >= PI and a > big_d:
                            big_d = a
                    if big > 0.0 and big < math.inf:  # a zero row is left to the LU (zero pivot), a
                        sc = 1.0 / big  # non-finite one to the loops' finiteness checks
                        share = min(share, big_d * sc)
                if sc != 1.0:
                    for j in range(N):
                        w[OJ + i * N + j] *= sc
                    for j in range(PI + 1):
                        w[OR + i * (PI + 1) + j] *= sc
        # J2 X = R  ->  X = [A | B̂]   (20), (108), (113)
        w[ORC] = lu_solve_flat(w, OJ + PI, N, OR, PI + 1, M, PI + 1)  # INLINE
        if NORM_ROWS:
            if share < w[ORC]:
                w[ORC] = share
    if w[ORC] == 0.0:  # J2 singular: no u̇ (the loops stop on the rcond)
        w[ORC + 1] = 0.0
    else:
        _reduced_solve(w, K, row)  # INLINE


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _reduced_solve(w, K, row):
    """The rest of ``rhs_ws`` once [A | B̂] is known (pasted into it by the generator)."""
    # T u̇ = V̂ with T = [A1; A2 Q], V̂ = [B̂; A2 P]  (22), (40), (44), (110), solved by block
    # elimination on the identity block of A1 = [−A  I]:  u̇_D = A u̇_I + B̂  (106), then
    # (A2 Q A2ᵀ) u̇_I = A2 (P − Q [0; B̂])  with A2ᵀ = [I; A]  — exact, allocation-free,
    # and p×p instead of n×n.  (With no constraints this is Q u̇ = P.)
    # W = Q A2ᵀ  (n×p)
    for i in range(N):
        for r in range(PI):
            acc = w[OQ + i * N + r]
            for k in range(M):
                acc += w[OQ + i * N + PI + k] * w[OR + k * (PI + 1) + r]
            w[OW + i * PI + r] = acc
    # Mr = A2 W  (p×p),  y = P − Q_{·D} B̂,  rhs = A2 y
    for r in range(PI):
        for c in range(PI):
            acc = w[OW + r * PI + c]
            for k in range(M):
                acc += w[OR + k * (PI + 1) + r] * w[OW + (PI + k) * PI + c]
            w[OMR + r * PI + c] = acc
    for i in range(N):
        acc = w[OP + i]
        for k in range(M):
            acc -= w[OQ + i * N + PI + k] * w[OR + k * (PI + 1) + PI]
        w[OY + i] = acc
    for r in range(PI):
        acc = w[OY + r]
        for k in range(M):
            acc += w[OR + k * (PI + 1) + r] * w[OY + PI + k]
        w[OUI + r] = acc
    # (111): u̇_I from the reduced system; its pivot ratio is the T condition estimate
    w[ORC + 1] = lu_solve_flat(w, OMR, PI, OUI, 1, PI, 1)  # INLINE
    for r in range(PI):
        K[row, N + PERM[r]] = w[OUI + r]
    for k in range(M):
        acc = w[OR + k * (PI + 1) + PI]
        for r in range(PI):
            acc += w[OR + k * (PI + 1) + r] * w[OUI + r]
        K[row, N + PERM[PI + k]] = acc


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _forces_paper(w, K, krow):
    """``_forces`` of the paper's solve with the declared partition."""
    for r in range(N):
        acc = -w[OPC + r]
        for c in range(N):
            acc += w[OQC + r * N + c] * K[krow, N + PERM[c]]
        w[OFC + r] = acc
    if M > 0:
        for i in range(M):  # J2ᵀ, in place
            for j in range(i + 1, M):
                a = w[OJ2C + i * M + j]
                w[OJ2C + i * M + j] = w[OJ2C + j * M + i]
                w[OJ2C + j * M + i] = a
        for a in range(M):
            w[OLAM + a] = w[OFC + PI + a]
        # runtime integers, not the module's constants: lu_solve_flat keeps one compiled copy
        # (numba compiles one per literal value; the projections call it the same way)
        zero = krow - krow
        one, m = zero + 1, zero + M
        lu_solve_flat(w, zero + OJ2C, m, zero + OLAM, one, m, one)
