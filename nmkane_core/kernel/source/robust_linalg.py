# ruff: noqa: F821
"""Generic compiled kernel, part 4b: the rank-robust solve's dense linear algebra with run-time
sizes (Cholesky of Q, triangular solves, Householder QR with column pivoting stopped at the
rank).  Not imported: appended to every generated kernel (:mod:`nmkane_core.kernel.codegen`)."""

import math

from numba import njit


# ------------------------------------------------------------------ dense kernels, run-time sizes
@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _chol(w, oa, ol, n):
    """A = L Lᵀ (Cholesky–Banachiewicz) for the n×n A at ``oa``, L (n×n, lower) at ``ol``;
    returns 1, or 0 when A is not positive definite."""
    for j in range(n):
        d = w[oa + j * n + j]
        for k in range(j):
            d -= w[ol + j * n + k] * w[ol + j * n + k]
        if not d > 0.0:
            return 0
        ljj = math.sqrt(d)
        w[ol + j * n + j] = ljj
        inv = 1.0 / ljj
        for i in range(j + 1, n):
            s = w[oa + i * n + j]
            for k in range(j):
                s -= w[ol + i * n + k] * w[ol + j * n + k]
            w[ol + i * n + j] = s * inv
        for i in range(j):
            w[ol + i * n + j] = 0.0
    return 1


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _fwd(w, ol, n, ob, k):
    """L X = B in place, B n×k (row stride k) at ``ob``."""
    for i in range(n):
        inv = 1.0 / w[ol + i * n + i]
        for c in range(k):
            s = w[ob + i * k + c]
            for l in range(i):
                s -= w[ol + i * n + l] * w[ob + l * k + c]
            w[ob + i * k + c] = s * inv


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _bwd_t(w, ol, n, ob):
    """Lᵀ x = b in place, b (n) at ``ob``."""
    for i in range(n - 1, -1, -1):
        s = w[ob + i]
        for l in range(i + 1, n):
            s -= w[ol + l * n + i] * w[ob + l]
        w[ob + i] = s / w[ol + i * n + i]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _qr_min_norm(w, ok, n, m, tol, max_rank):
    """The heart of the robust solve, steps 3–5 of docs/closed-loops.md §7: for K (n×m, row
    stride m) at ``ok`` and e (m) at OEE, the smallest z with Kᵀz = e on the independent
    equations, z = Z_r R11⁻ᵀ e[piv] at OZZ.

    Columns shorter than ``tol`` times the longest are vanishing (dropped); the others are
    scaled to unit length (with their e), then Householder QR with column pivoting (the
    remaining column of largest norm, the first on a tie) runs until the pivot falls to
    ``tol`` times the first one or ``max_rank`` steps.  Leaves R and the reflectors in K,
    the norms at ONRM, the column order at OPIV (kept ones first), y at OYY, 1.0 at ODROP for
    every dropped equation, the smallest kept pivot at w[OSV + SV_PIVOT] and the largest
    residual of the dropped equations (in e's units) at w[OSV + SV_RESIDUAL]; returns the rank."""
    kept = _scale_columns(w, ok, n, m, tol)
    rank = _pivoted_qr(w, ok, n, m, kept, tol, max_rank)
    w[OSV + SV_PIVOT] = _solve_r11_t(w, ok, m, rank)
    w[OSV + SV_RESIDUAL] = _dropped_residual(w, ok, m, rank, kept)
    _apply_reflectors(w, ok, n, m, rank)
    return rank


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _scale_columns(w, ok, n, m, tol):
    """Column norms at ONRM; columns longer than ``tol`` times the longest scaled to unit
    length (with their e) and listed first at OPIV, the vanishing ones after them (ODROP
    1.0); returns how many are kept."""
    big = 0.0
    for col in range(m):
        s = 0.0
        for i in range(n):
            s += w[ok + i * m + col] * w[ok + i * m + col]
        nr = math.sqrt(s)
        w[ONRM + col] = nr
        w[ODROP + col] = 1.0
        if nr > big:
            big = nr
    kept = 0
    for col in range(m):
        nr = w[ONRM + col]
        if big > 0.0 and nr > tol * big:
            inv = 1.0 / nr
            for i in range(n):
                w[ok + i * m + col] *= inv
            w[OEE + col] *= inv
            w[OPIV + kept] = col
            w[ODROP + col] = 0.0
            kept += 1
    pos = kept
    for col in range(m):  # the vanishing ones after the kept ones
        if w[ODROP + col] == 1.0:
            w[OPIV + pos] = col
            pos += 1
    return kept


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _pivoted_qr(w, ok, n, m, kept, tol, max_rank):
    """Householder QR with column pivoting of the kept columns, until the pivot falls to
    ``tol`` times the first or ``max_rank`` steps: R and the reflectors in K, β at OBETA;
    returns the rank."""
    rank = 0
    first = 0.0
    steps = min(n, kept, max_rank)
    for k in range(steps):
        best = -1.0
        jbest = k
        for jj in range(k, kept):
            col = int(w[OPIV + jj])
            s = 0.0
            for i in range(k, n):
                s += w[ok + i * m + col] * w[ok + i * m + col]
            if s > best:
                best = s
                jbest = jj
        nk = math.sqrt(best)
        if k == 0:
            first = nk
        if nk <= tol * first or nk == 0.0:
            break
        tmp = w[OPIV + k]
        w[OPIV + k] = w[OPIV + jbest]
        w[OPIV + jbest] = tmp
        _reflect(w, ok, n, m, k, kept, nk)
        rank = k + 1
    return rank


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _reflect(w, ok, n, m, k, kept, nk):
    """Step k of the QR: the reflector of pivot column OPIV[k] (norm ``nk`` below row k),
    applied to the kept columns after it."""
    col = int(w[OPIV + k])
    x0 = w[ok + k * m + col]
    alpha = -nk if x0 >= 0.0 else nk
    v0 = x0 - alpha
    inv = 1.0 / v0
    for i in range(k + 1, n):
        w[ok + i * m + col] *= inv
    beta = -v0 / alpha
    w[OBETA + k] = beta
    w[ok + k * m + col] = alpha
    for jj in range(k + 1, kept):
        c2 = int(w[OPIV + jj])
        d = w[ok + k * m + c2]
        for i in range(k + 1, n):
            d += w[ok + i * m + col] * w[ok + i * m + c2]
        d *= beta
        w[ok + k * m + c2] -= d
        for i in range(k + 1, n):
            w[ok + i * m + c2] -= d * w[ok + i * m + col]


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _solve_r11_t(w, ok, m, rank):
    """R11ᵀ y = e[piv[:r]] into OYY; returns the smallest |pivot| (at most 1)."""
    pmin = 1.0
    for k in range(rank):
        col = int(w[OPIV + k])
        s = w[OEE + col]
        for i in range(k):
            s -= w[ok + i * m + col] * w[OYY + i]
        rkk = w[ok + k * m + col]
        w[OYY + k] = s / rkk
        if abs(rkk) < pmin:
            pmin = abs(rkk)
    return pmin


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _dropped_residual(w, ok, m, rank, kept):
    """ODROP 1.0 for every equation beyond the rank; returns their largest residual, in e's units."""
    res = 0.0
    for jj in range(rank, m):
        col = int(w[OPIV + jj])
        w[ODROP + col] = 1.0
        s = w[OEE + col]
        if jj < kept:
            for i in range(rank):
                s -= w[ok + i * m + col] * w[OYY + i]
            s *= w[ONRM + col]
        if abs(s) > res or not math.isfinite(s):
            res = abs(s)
    return res


@njit(cache=True, nogil=True, fastmath=FM, error_model="numpy")
def _apply_reflectors(w, ok, n, m, rank):
    """z = H_0 … H_{r−1} [y; 0] into OZZ."""
    for i in range(n):
        w[OZZ + i] = w[OYY + i] if i < rank else 0.0
    for k in range(rank - 1, -1, -1):
        col = int(w[OPIV + k])
        d = w[OZZ + k]
        for i in range(k + 1, n):
            d += w[ok + i * m + col] * w[OZZ + i]
        d *= w[OBETA + k]
        w[OZZ + k] -= d
        for i in range(k + 1, n):
            w[OZZ + i] -= d * w[ok + i * m + col]
